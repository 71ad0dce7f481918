"""Stage 1 of the pipeline: read a model file and validate it into plain data."""
from .load import METHODS, load_model, load_model_text
from .types import (AngularVelocity, Body, BodyPoint, Constraint, Distance, Force,
                    Initial, Load, Model, Point, PointOnLine, PointRef, SimulateDefaults,
                    Spring, Torque, Vector, Where)

__all__ = ["METHODS", "load_model", "load_model_text", "AngularVelocity", "Body",
           "BodyPoint", "Constraint", "Distance", "Force", "Initial", "Load", "Model",
           "Point", "PointOnLine", "PointRef", "SimulateDefaults", "Spring", "Torque",
           "Vector", "Where"]
