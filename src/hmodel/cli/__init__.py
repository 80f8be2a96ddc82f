"""The ``hmodel`` command line (a thin layer over the library)."""
