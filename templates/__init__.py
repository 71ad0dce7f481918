"""Jinja2 templates of the generated sources; installed as the package
``fccgen.templates`` (see pyproject.toml) and rendered by ``fccgen.render``."""
