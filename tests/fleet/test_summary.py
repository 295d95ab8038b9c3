"""The fleet's tables and flags (issue 16, item 1): robust z-scores by median and MAD, outlier
flags, model files flattened into parameter columns, CSV and Parquet with the same content."""

import math

import numpy as np
import pyarrow.parquet as pq
import pytest

from piezohyst.fleet import flatten_parameters, outliers, robust_z, write_table


def test_robust_z_is_the_modified_z_score():
    x = np.array([10.0, 11.0, 9.0, 10.5, 9.5, 30.0, np.nan])
    z = robust_z(x)
    med, mad = 10.25, 0.75  # of the finite six: |x - 10.25| = .25, .75, 1.25, .25, .75, 19.75
    assert np.allclose(z[:6], 0.6745 * (x[:6] - med) / mad, rtol=0, atol=1e-15)
    assert math.isnan(z[6])
    # one wild value does not hide itself by inflating the spread, as the standard z-score does
    assert z[5] > 3.5 and abs((x[5] - np.nanmean(x)) / np.nanstd(x)) < 2.5
    # more than half equal: MAD 0, off-median values are infinitely far
    assert list(robust_z([1.0, 1.0, 1.0, 2.0])) == [0.0, 0.0, 0.0, math.inf]


def test_outliers_flag_the_column_and_need_five_values():
    rows = [{"a": v, "b": 1.0 + 0.01 * i} for i, v in enumerate([1.0, 1.1, 0.9, 1.05, 0.95, 4.0])]
    flags = outliers(rows, ["a", "b"])
    assert flags[:5] == [[]] * 5 and len(flags[5]) == 1 and flags[5][0].startswith("a (z = +")
    assert outliers(rows[:4], ["a"]) == [[]] * 4  # too few to judge


def test_model_files_flatten_into_parameter_columns():
    doc = {
        "kind": "gpi",
        "parameters": {"thresholds": [0.0, 0.1], "weights": [1.0, 0.5], "p0": 0.3, "rising": {"kind": "identity"}},
        "output_map": {"offset": -0.1, "gain": 2.0},
    }
    assert flatten_parameters(doc) == {
        "p.thresholds[0]": 0.0,
        "p.thresholds[1]": 0.1,
        "p.weights[0]": 1.0,
        "p.weights[1]": 0.5,
        "p.p0": 0.3,
        "p.output_map.offset": -0.1,
        "p.output_map.gain": 2.0,
    }
    stage = {"kind": "stage", "mechanics": {"mass": 0.01}, "cemf": {"alpha": 0.3, "drive": "charge"}}
    assert flatten_parameters(stage) == {"p.mechanics.mass": 0.01, "p.cemf.alpha": 0.3}


def test_csv_and_parquet_hold_the_same_rows(tmp_path):
    rows = [
        {"record": "r0", "status": "ok", "p.a": 0.1 + 0.2, "error": None},
        {"record": "r1", "status": "failed", "p.a": None, "error": "no such file, 'x'"},
    ]
    cols = ["record", "status", "p.a", "error"]
    write_table(rows, cols, tmp_path / "s.csv", tmp_path / "s.parquet")
    text = (tmp_path / "s.csv").read_text().splitlines()
    assert text == ["record,status,p.a,error", "r0,ok,0.30000000000000004,", "r1,failed,,\"no such file, 'x'\""]
    t = pq.read_table(tmp_path / "s.parquet")
    assert t.column_names == cols and str(t.schema.field("p.a").type) == "double"
    assert t.to_pylist() == [
        {"record": "r0", "status": "ok", "p.a": 0.30000000000000004, "error": None},
        {"record": "r1", "status": "failed", "p.a": None, "error": "no such file, 'x'"},
    ]
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("n", [0, 3])
def test_robust_z_of_few_values(n):
    assert robust_z(np.full(n, np.nan)).shape == (n,)
