"""Every public import path of the flat package (before the split into wings) keeps working:
the former ``piezohyst.__all__`` from ``piezohyst``, every former module path with every public
name it defined, and the provenance names from ``piezohyst`` with a ``DeprecationWarning``
naming their new home. The lists are the former package's, hard-coded."""

import importlib
import subprocess
import sys
import warnings

import pytest

import piezohyst

#: ``piezohyst.__all__`` before the split.
OLD_ALL = [
    "A7075_YOUNGS_MODULUS",
    "ABSMC",
    "CSS",
    "DE",
    "ILC",
    "MPSO",
    "PI",
    "PID",
    "PSO",
    "SCHEMA_VERSION",
    "SEED2_TABLE1",
    "SMC",
    "Amplifier",
    "BoucWen",
    "BoucWenBenchmark",
    "CemfCoefficients",
    "CemfFeedforward",
    "ClosedLoopResult",
    "Compensated",
    "ComputationError",
    "Creep",
    "Dahl",
    "DataError",
    "Duhem",
    "Envelope",
    "FitResult",
    "FlexureStage",
    "GeneralizedPI",
    "GeneralizedPlay",
    "HysteresisModel",
    "IdentificationResult",
    "IntermediateResult",
    "Inverse",
    "InverseFeedforward",
    "LeafSpring",
    "NotInvertibleError",
    "OpenLoop",
    "OptimizeResult",
    "Optimizer",
    "OutputExistsError",
    "ParameterError",
    "ParameterTypeError",
    "PiezohystError",
    "PlayOperator",
    "Preisach",
    "RateDependentPI",
    "Record",
    "Sensor",
    "Stage",
    "StageInfo",
    "StageParameters",
    "StageResponse",
    "TuningResult",
    "UnreachableError",
    "VelocityObserver",
    "batch_rmse",
    "batch_simulate",
    "chirp",
    "closed_loop",
    "closed_loop_batch",
    "fit_linear",
    "fit_metrics",
    "hysteresis_percent",
    "identify",
    "identify_boucwen_benchmark",
    "identify_cemf",
    "identify_mpi",
    "identify_pi",
    "identify_preisach",
    "identify_vp",
    "linearity_error",
    "load_model",
    "load_record",
    "load_train_multisine",
    "load_yan9a_model_record",
    "minimize",
    "model_from_dict",
    "mpi_seed2",
    "multisine",
    "seed1_stage",
    "sine",
    "stage_from_model",
    "staircase",
    "track",
    "tracking_metrics",
    "triangle",
    "tune",
    "variable_amplitude_sine",
    "virtual_stage",
]

#: The provenance names that left ``__all__`` (importable, deprecated, from ``piezohyst``).
PROVENANCE = ["SEED2_TABLE1", "mpi_seed2", "seed1_stage"]

#: Every former module and the public names it defined.
OLD_MODULES = {
    "batch": [
        "batch_rmse",
        "batch_simulate",
    ],
    "benchmarks": [
        "BENCHMARKS",
        "Benchmark",
        "find_bench_dir",
        "main",
        "run_suite",
        "select",
        "summarize",
        "to_markdown",
        "update_readme",
    ],
    "boucwen_benchmark": [
        "BoucWenBenchmark",
        "DEFAULT_BOUNDS",
        "FS",
        "IDENTIFY_PARAMETERS",
        "INTERPOLATIONS",
        "UPSAMPLE",
        "decimate",
        "identify_boucwen_benchmark",
        "load_train_multisine",
        "upsample",
    ],
    "cli": [
        "main",
    ],
    "control": [
        "ABSMC",
        "CemfFeedforward",
        "Compensated",
        "ILC",
        "InverseFeedforward",
        "OpenLoop",
        "PID",
        "SMC",
        "VelocityObserver",
        "cemf_model_parameters",
        "is_controller",
        "with_gains",
    ],
    "creep": [
        "Creep",
        "creep_from",
        "creep_parts",
    ],
    "data": [
        "H5PY_HINT",
        "HDF5_SUFFIXES",
        "MAT_SUFFIXES",
        "NPY_SUFFIXES",
        "NPZ_SUFFIXES",
        "Record",
        "SUPPORTED_SUFFIXES",
        "TEXT_SUFFIXES",
        "TIME_RTOL",
        "load_record",
        "load_yan9a_model_record",
    ],
    "demo": [
        "REPORT_FILES",
        "run_demo",
    ],
    "differential": [
        "BoucWen",
        "Dahl",
        "Duhem",
    ],
    "errors": [
        "ComputationError",
        "DataError",
        "NotInvertibleError",
        "OutputExistsError",
        "ParameterError",
        "ParameterTypeError",
        "PiezohystError",
        "UnreachableError",
    ],
    "experiments": [
        "SEED1_TABLE3",
        "SEED2_TABLE2",
        "SEED2_TABLE3",
        "SEED2_TABLE4",
        "excitation",
        "identify_stage_cemf",
        "identify_stage_mpi",
        "loop_lag",
        "measure",
        "mpi_validation",
        "seed1_case_studies",
        "seed2_compensation",
        "steady_sine",
        "timed",
    ],
    "export_c": [
        "CONTROLLER_KINDS",
        "CONTROLLER_PARAMS",
        "CONTROLLER_SCHEMA_VERSION",
        "EXAMPLE_PERIOD",
        "ExportedController",
        "FAMILY_CODES",
        "LINK_LIBS",
        "controller_from_dict",
        "controller_to_dict",
        "demo_input_range",
        "example_plan",
        "export_c",
        "header_path",
        "library_path",
        "load_controller",
        "row_names",
        "save_controller",
    ],
    "flexure": [
        "A7075_YOUNGS_MODULUS",
        "CemfCoefficients",
        "FlexureStage",
        "LeafSpring",
        "seed1_stage",
    ],
    "identify": [
        "CEMF_PARAMETERS",
        "FitResult",
        "HUBER_K",
        "IdentificationResult",
        "KINDS",
        "LOSSES",
        "STRUCTURES",
        "default_huber_delta",
        "fit_linear",
        "fit_metrics",
        "huber_cost",
        "identify",
        "identify_cemf",
        "identify_mpi",
        "identify_pi",
        "identify_preisach",
        "minimize_huber",
    ],
    "metrics": [
        "hysteresis_percent",
        "linearity_error",
        "max_error",
        "rmse",
        "tracking_metrics",
    ],
    "model": [
        "HysteresisModel",
        "Inverse",
        "SCHEMA_VERSION",
        "load_model",
        "model_from_dict",
    ],
    "optimize": [
        "CSS",
        "DE",
        "IntermediateResult",
        "METHODS",
        "MPSO",
        "OptimizeResult",
        "Optimizer",
        "PSO",
        "css_charges",
        "css_forces",
        "minimize",
    ],
    "pi": [
        "Envelope",
        "EnvelopeInverse",
        "GeneralizedPI",
        "GeneralizedPlay",
        "PI",
        "PlayOperator",
        "RateDependentPI",
        "SEED2_TABLE1",
        "mpi_seed2",
    ],
    "preisach": [
        "Preisach",
    ],
    "references": [
        "MAX_SAMPLES",
        "chirp",
        "multisine",
        "sine",
        "staircase",
        "triangle",
        "variable_amplitude_sine",
    ],
    "report": [
        "write_report",
    ],
    "simulation": [
        "ClosedLoopResult",
        "closed_loop",
        "closed_loop_batch",
        "seed_from",
    ],
    "stage": [
        "Amplifier",
        "MAX_CREEP",
        "Sensor",
        "Stage",
        "StageInfo",
        "StageParameters",
        "StageResponse",
        "virtual_stage",
    ],
    "tuning": [
        "TuningResult",
        "stage_from_model",
        "track",
        "tune",
    ],
    "varpro": [
        "DEFAULT_ITERATIONS",
        "ENVELOPES",
        "PAD",
        "VP_KINDS",
        "identify_vp",
        "vp_parameters",
    ],
}


def test_the_old_all_is_importable_from_the_top():
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        for name in OLD_ALL:
            if name in PROVENANCE:
                continue
            assert getattr(piezohyst, name) is not None, name
            exec(f"from piezohyst import {name}", {})


def test_provenance_names_left_all_and_live_in_papers():
    from piezohyst import papers

    assert not set(PROVENANCE) & set(piezohyst.__all__)
    assert set(OLD_ALL) - set(PROVENANCE) <= set(piezohyst.__all__)
    for name in PROVENANCE:
        assert name in papers.__all__
        with pytest.warns(DeprecationWarning, match=rf"piezohyst\.papers\.{name}"):
            old = getattr(piezohyst, name)
        assert old is getattr(papers, name)


def test_from_import_of_a_provenance_name_warns():
    with pytest.warns(DeprecationWarning, match="piezohyst.papers"):
        from piezohyst import mpi_seed2
    assert mpi_seed2 is piezohyst.papers.mpi_seed2


@pytest.mark.parametrize("module", sorted(OLD_MODULES))
def test_every_old_module_path_and_name(module):
    mod = importlib.import_module(f"piezohyst.{module}")
    missing = [name for name in OLD_MODULES[module] if not hasattr(mod, name)]
    assert missing == [], f"piezohyst.{module} lost {missing}"
    exec(f"import piezohyst.{module}", {})
    exec(f"from piezohyst.{module} import {', '.join(OLD_MODULES[module])}", {})


@pytest.mark.parametrize("module", sorted(OLD_MODULES))
def test_an_old_module_path_is_the_new_module(module):
    """An alias, not a copy: the old path gives the very module object of its new home, and
    that module keeps its own name and spec."""
    mod = importlib.import_module(f"piezohyst.{module}")
    assert sys.modules[f"piezohyst.{module}"] is mod
    assert sys.modules[mod.__name__] is mod
    assert mod.__spec__.name == mod.__name__
    if module not in ("identify", "optimize", "control", "cli", "errors"):
        assert mod.__name__ != f"piezohyst.{module}", f"piezohyst.{module} is still a flat module"


def test_old_module_attributes_of_the_package():
    """``import piezohyst`` then ``piezohyst.pi.PI``, as the flat package allowed."""
    assert piezohyst.pi.PI is piezohyst.PI
    assert piezohyst.stage.Stage is piezohyst.Stage
    assert piezohyst.experiments.measure is piezohyst.plant.measure


def test_readme_walkthrough_imports():
    from piezohyst.experiments import excitation, measure
    from piezohyst.identify import identify_mpi
    from piezohyst.stage import Amplifier, Stage, StageParameters

    assert callable(excitation) and callable(measure) and callable(identify_mpi)
    assert Amplifier and Stage and StageParameters


@pytest.mark.parametrize("argv", [["-m", "piezohyst", "--help"], ["-m", "piezohyst.cli", "--help"]])
def test_command_line_entry_points(argv):
    out = subprocess.run([sys.executable, *argv], capture_output=True, text=True, check=True).stdout
    assert "identify" in out and "export-c" in out


def test_console_script_target():
    """``piezohyst = "piezohyst.cli:main"`` (pyproject.toml)."""
    from piezohyst.cli import main

    assert main is importlib.import_module("piezohyst.cli.main").main
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
