"""Stage 2 of the pipeline: the element plan (coordinates, element classes, parameters)."""
from .build import Element, Plan, make_plan
from .classes import ElementClass
from ..model.geometry import body_frame_numbers, body_rotation, point_coefficients

__all__ = ["Element", "ElementClass", "Plan", "make_plan", "body_frame_numbers",
           "body_rotation", "point_coefficients"]
