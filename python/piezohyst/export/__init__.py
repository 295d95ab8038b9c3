"""Export: models and controllers as C code against the C API (:mod:`.c`, the former
module ``piezohyst.export_c``; MIMO models: :mod:`.c_mimo`)."""

from .c import controller_from_dict, controller_to_dict, export_c, load_controller, save_controller
from .c_mimo import MIMO_EXPORT_FILES, export_c_mimo, mimo_row

__all__ = [
    "MIMO_EXPORT_FILES",
    "controller_from_dict",
    "controller_to_dict",
    "export_c",
    "export_c_mimo",
    "load_controller",
    "mimo_row",
    "save_controller",
]
