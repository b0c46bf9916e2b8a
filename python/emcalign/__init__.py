"""emcalign in Python: the C++ library the command-line tool runs, with numpy arrays.

Units are the library's: cm, MeV, rad (a name ending in _deg or _mev says otherwise).
Every refused input or failed step raises emcalign.Error with the message the
command-line tool prints. See docs/python.md.
"""

from ._emcalign import (  # noqa: F401  (the module's public names)
    CUTS,
    DERIVED,
    PARAMETERS,
    PHYSICAL,
    Conditions,
    Detector,
    Error,
    FitResult,
    compare,
    correct,
    correct_directions,
    file_units,
    fit,
    forward,
    from_physical,
    inverse,
    read_alignment,
    read_events,
    read_output,
    read_profile,
    select,
    simulate,
    to_physical,
    write_alignment,
)

__all__ = [
    "CUTS",
    "DERIVED",
    "PARAMETERS",
    "PHYSICAL",
    "Conditions",
    "Detector",
    "Error",
    "FitResult",
    "compare",
    "correct",
    "correct_directions",
    "file_units",
    "fit",
    "forward",
    "from_physical",
    "inverse",
    "read_alignment",
    "read_events",
    "read_output",
    "read_profile",
    "select",
    "simulate",
    "to_physical",
    "write_alignment",
]
