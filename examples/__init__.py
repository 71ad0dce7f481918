"""The example models, shipped with fccgen: ``fccgen.example_path(name)`` is the path
of one, ``fccgen examples [DIR]`` copies them into a folder (examples/README.md)."""
