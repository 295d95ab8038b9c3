import numpy as np
import pytest
from hypothesis import settings

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True)
settings.load_profile("ci")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def random_walk(rng, n, scale=1.0):
    """A bounded random input with many reversals."""
    return scale * np.cumsum(rng.normal(size=n)) / np.sqrt(n)
