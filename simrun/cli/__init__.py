"""The ``simrun`` command line: click layers over the library."""
