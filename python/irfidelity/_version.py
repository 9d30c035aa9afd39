"""The package's version (pyproject.toml's), apart from the package so that the modules that
record it (reports, the command line) need not import the package that imports them."""

__version__ = "0.2.0"
