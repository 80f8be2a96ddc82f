"""Example data shipped with hmodel, named ``example:NAME`` wherever a file is expected.

- ``example:kfs``: Karlsruhe fine sand, 25 drained triaxial compression tests (five densities,
  e0 0.70–1.00, at 50–400 kPa, to 20 % axial strain), the KFS file of the Sand Triaxial Test
  Database compiled by Huan Wang (Norwegian Geotechnical Institute), CC BY 4.0,
  DOI 10.4121/086847a6-ba39-4d66-973b-6b93028c7ad8; the tests are those of Wichtmann &
  Triantafyllidis (2016), Acta Geotechnica 11(4):739–761, doi:10.1007/s11440-015-0402-z.
  ``kfs/README.md`` beside the file keeps this attribution and the licence.

>>> example_path("example:kfs").name
'drained-karlsruhe-compilation.csv'
>>> resolve("results/d100.csv")
'results/d100.csv'
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError

PREFIX = "example:"
#: name -> file, relative to this package
EXAMPLES = {"kfs": "kfs/drained-karlsruhe-compilation.csv"}


def example_path(spec: str) -> Path:
    """The shipped file of ``example:NAME`` (a one-line InputError naming the examples)."""
    name = spec[len(PREFIX):] if spec.startswith(PREFIX) else spec
    if name not in EXAMPLES:
        raise InputError(f"no example {name!r} (examples: {', '.join(PREFIX + k for k in EXAMPLES)})")
    return Path(__file__).parent / EXAMPLES[name]


def resolve(path: str) -> str:
    """``path`` itself, or the shipped file when it reads ``example:NAME``."""
    return str(example_path(path)) if str(path).startswith(PREFIX) else path
