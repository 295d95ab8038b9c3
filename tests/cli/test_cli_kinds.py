"""`piezohyst identify --model`: one home for the list of model kinds, the identify
dispatcher's registry (``piezohyst.identify.KINDS``)."""

import argparse

from piezohyst.cli import identify as cli_identify
from piezohyst.cli.main import _parser
from piezohyst.identify import KINDS


def _identify_action(name):
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    return next(a for a in sub.choices["identify"]._actions if a.dest == name)


def test_model_choices_are_the_registry():
    model = _identify_action("model")
    assert tuple(model.choices) == KINDS
    assert cli_identify._KINDS is KINDS


def test_model_help_lists_every_kind_in_order():
    assert _identify_action("model").help.startswith(f"model to identify: {', '.join(KINDS)} (required).")
