"""fccgen's version: what generated files, result files and exports record."""
__version__ = "0.1.0"
