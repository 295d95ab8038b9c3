"""Per-set means of per-record values: the one home of "average over the realizations of
each set" (an excitation level of multisine records), which the identification's weights,
probes, scores and reports all need."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike


def set_means(values: ArrayLike, labels: Sequence[str]) -> dict[str, float]:
    """The mean of ``values[i]`` (each a number or an array) over the records ``i`` of each
    set, the sets in their order of first appearance in ``labels``.

    Parameters
    ----------
    values : array_like
        One number or array per record (the first axis: the records).
    labels : sequence of str
        The set of each record.

    Returns
    -------
    dict of str to float
        Each set's mean.

    Examples
    --------
    >>> set_means([[1.0, 3.0], [5.0, 7.0], [0.0, 0.0]], ("a", "a", "b"))
    {'a': 4.0, 'b': 0.0}
    """
    v = np.asarray(values, dtype=np.float64)
    if v.shape[:1] != (len(labels),):
        raise ValueError(f"values has {v.shape[:1]} records, labels {len(labels)}")
    lab = np.asarray(labels, dtype=object)
    return {s: float(v[lab == s].mean()) for s in dict.fromkeys(labels)}
