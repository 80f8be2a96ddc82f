"""A stability study as ``hmodel stability`` runs it: one path (a laboratory test or a loading
program) analysed (:func:`run_study`), with the title of its figures and the report of what
was found (:class:`StabilityStudy`); :func:`hmodel.stability.output.write_study` writes it."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import InputError
from ..loading.named_paths import AXIAL_STEP
from ..rev.sphere import Sphere
from .analysis import along_biaxial, along_program, along_triaxial
from .locate import PathStability

#: The laboratory tests a study follows: the 2D model's biaxial test, the 3D model's triaxial
#: test.
TESTS = ("biaxial", "triaxial")


@dataclass(frozen=True)
class StabilityStudy:
    """The stability of one path (:class:`~hmodel.stability.locate.PathStability`), the title
    of its figures and, for a laboratory test, the axial strain asked for and its increment
    (None for a program, which catches its own failures)."""

    stability: PathStability
    title: str
    axial_strain: float | None = None
    step: float = AXIAL_STEP

    @property
    def reached(self) -> float:
        """The magnitude of the axial strain reached since consolidation (0: none)."""
        ps = self.stability
        return float(abs(ps.shear_strain[-1])) if len(ps.shear_strain) else 0.0

    @property
    def ended_early(self) -> bool:
        """Whether a laboratory test stopped short of its axial strain by more than half an
        increment: an increment it could not solve."""
        return self.axial_strain is not None and self.reached < self.axial_strain - 0.5 * self.step

    def report(self, written: object = None) -> list[str]:
        """The lines that tell what the study found: where the test ended when it ended early,
        then the bifurcation-domain entry and the loss of controllability (axial strain, row,
        how found), and the folder ``written`` when given."""
        ps = self.stability
        fmt = lambda v: "none" if not math.isfinite(v) else f"{100 * v:.3f} %"  # noqa: E731
        row = lambda v: "" if not math.isfinite(v) else f" (row {v:.0f})"  # noqa: E731
        by = f", by the {ps.bifurcation_by}" if ps.bifurcation_by else ""
        lines = []
        if self.ended_early:
            lines.append(f"the test ended at axial strain {100 * self.reached:.3f} %: the next "
                         f"increment could not be solved")
        lines.append(f"bifurcation domain entered at axial strain {fmt(ps.bifurcation)}"
                     f"{row(ps.bifurcation_step)}{by}; loss of controllability at "
                     f"{fmt(ps.controllability)}{row(ps.controllability_step)}"
                     + ("" if written is None else f"; wrote {written}"))
        return lines


def run_study(params, *, program=None, test: str = "biaxial", p0: float = 2e5,
              axial_strain: float = 0.1, undrained: bool = False, extension: bool = False,
              sphere: Sphere | None = None, at: tuple[float, ...] = (), step: float = AXIAL_STEP,
              stress_magnitude: float = 1e-3, rendulic: bool = True, every: int = 10,
              n_probes: int = 72, magnitude: float | None = None, shear: bool = False,
              loading_probe: bool = True, controllability: str | None = None,
              progress: Callable[[float], None] | None = None) -> StabilityStudy:
    """Stability along a loading ``program`` (:func:`~hmodel.stability.analysis.along_program`;
    the test's arguments, from ``test`` to ``rendulic``, do not apply), or along the laboratory
    ``test`` (:data:`TESTS`) from ``p0`` [Pa] to ``axial_strain``: the 2D model's biaxial test
    (:func:`~hmodel.stability.analysis.along_biaxial`) or the 3D model's triaxial test on
    ``sphere`` (default ``Sphere()``; :func:`~hmodel.stability.analysis.along_triaxial`).
    ``every``, ``n_probes``, ``magnitude``, ``shear``, ``loading_probe``, ``controllability``,
    ``progress``: as :func:`~hmodel.stability.analysis.along_program`."""
    common = {"every": every, "n_probes": n_probes, "magnitude": magnitude, "shear": shear,
              "progress": progress, "loading_probe": loading_probe,
              "controllability": controllability}
    if program is not None:
        return StabilityStudy(along_program(program, params, **common),
                              f"program {program.name}")
    if test not in TESTS:
        raise InputError(f"the test must be one of {', '.join(TESTS)}, got {test!r}")
    drainage = "undrained" if undrained else "drained"
    if test == "triaxial":
        sphere = sphere if sphere is not None else Sphere()
        ps = along_triaxial(params, p0, axial_strain, undrained, extension, sphere, at=at,
                            step=step, stress_magnitude=stress_magnitude, rendulic=rendulic,
                            **common)
        title = (f"{drainage} triaxial {'extension' if extension else 'compression'}, p0 = "
                 f"{p0 / 1e3:g} kPa (3D, Lebedev order {sphere.order}, "
                 f"{sphere.n_azimuth} azimuths)")
    else:
        ps = along_biaxial(params, p0, axial_strain, undrained, at=at, step=step,
                           stress_magnitude=stress_magnitude, **common)
        title = f"{drainage} biaxial, p0 = {p0 / 1e3:g} kPa"
    return StabilityStudy(ps, title, axial_strain, step)
