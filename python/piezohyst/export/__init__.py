"""Export: models and controllers as C code against the C API (:mod:`.c`, the former
module ``piezohyst.export_c``)."""

from .c import controller_from_dict, controller_to_dict, export_c, load_controller, save_controller

__all__ = ["controller_from_dict", "controller_to_dict", "export_c", "load_controller", "save_controller"]
