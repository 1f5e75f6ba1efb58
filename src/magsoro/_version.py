"""Package version, kept in a leaf module so that modules can read it without importing the package root."""

__version__ = "0.1.0"
