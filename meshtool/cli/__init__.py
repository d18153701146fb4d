"""The ``meshtool`` and ``obj2bin`` command lines: click layers over the library and the one reporting layer."""
