"""The mechanism level (DESIGN section 2b): bodies, joints, drivers, loads and events,
lowered onto the points, vectors and constraints of the model level."""
