"""Named variants of the H-model (``--model NAME``, ``hmodel models``): the published model
(the default, unchanged) and the options that extend it, each a :class:`ModelVariant`.

A variant says how a test's initial state follows from what was measured of the specimen
(today: its void ratio e0) and is recorded by a calibration, so that a calibrated model runs
again, as it was fitted, at another density and pressure.

>>> get_variant("sand").name
'axisym-mix'
>>> get_variant("published").uses_e0
False
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from types import MappingProxyType

from .errors import InputError
from .params import Params
from .rev.density import alpha0_for_void_ratio, largest_alpha0

DEFAULT = "published"


@dataclass(frozen=True)
class ModelVariant:
    """A named variant of the H-model.

    Attributes
    ----------
    name, description : str
    uses_e0 : bool
        Whether a test's void ratio sets its initial state: α0 follows e0 through the REV's
        initial volume (:func:`hmodel.rev.density.alpha0_for_void_ratio`), from the α0 the
        parameters give at the reference void ratio e_ref.
    options : tuple of (str, str)
        The cell's mechanisms this variant switches on (:class:`~hmodel.params.Params` fields
        and values, docs/mechanisms.md), applied to every parameter set it runs (pairs, not a
        mapping: a variant travels to worker processes, pickled).
    fitted : tuple of str
        The parameters a calibration of this variant fits unless told otherwise (``--fit``).
    """

    name: str
    description: str
    uses_e0: bool = False
    options: tuple[tuple[str, str], ...] = ()
    fitted: tuple[str, ...] = ("kn", "kt_kn", "phi_g", "alpha0")

    def apply(self, params: Params) -> Params:
        """``params`` with this variant's mechanisms on (a mechanism has two values, off and
        the variant's: a variant cannot contradict a parameter set, only switch it on)."""
        return replace(params, **dict(self.options)) if self.options else params

    def initial_params(self, params: Params, dim: int, e0: float | None = None,
                       e_ref: float | None = None) -> Params:
        """The parameters of a specimen at void ratio ``e0``, with this variant's mechanisms on
        (:meth:`apply`); α0 unchanged when the variant does not use e0 or no e0 is given."""
        params = self.apply(params)
        if not self.uses_e0 or e0 is None:
            return params
        if e_ref is None:
            raise InputError(f"model {self.name} needs the reference void ratio e_ref at which alpha0 is given "
                             f"(a calibration records it)")
        return replace(params, alpha0=alpha0_for_void_ratio(params, dim, e0, e_ref))

    def default_bounds(self, params: Params, dim: int, e0s: Sequence[float], e_ref: float | None) -> dict:
        """Search ranges (CLI units) this variant needs of a calibration on tests at void ratios
        ``e0s``: α0 (at ``e_ref``) low enough that the loosest test is within the loosest cell."""
        if not self.uses_e0 or e_ref is None:
            return {}
        top = math.floor(10 * math.degrees(largest_alpha0(params, dim, max(e0s), e_ref))) / 10
        low = 31.0
        if ("cross_contacts", "frictionless") in self.options and dim == 3:
            # The densest test's cells must open at 45 deg or more (below, the two hexagons of an
            # unloaded bi-hexagon overlap): the alpha0 at e_ref that maps the densest e0 there.
            densest = replace(params, alpha0=_lowest_touching_alpha0(params.alpha0_spread))
            try:
                low = math.ceil(10 * math.degrees(alpha0_for_void_ratio(densest, dim, e_ref, min(e0s)))) / 10
            except InputError:  # the touching angle itself lies beyond the loosest cell
                low = math.inf
            if low >= top:
                raise InputError(f"model {self.name} cannot span void ratios {min(e0s):g} to {max(e0s):g} "
                                 f"(alpha0_spread {params.alpha0_spread:g}): the densest needs alpha0 >= "
                                 f"{low:g} deg at e_ref = {e_ref:g} for its hexagons not to overlap, the "
                                 f"loosest <= {top:g}")
        return {"alpha0": (low, top)}


def _lowest_touching_alpha0(spread: float) -> float:
    """The α0 [rad] whose lowest opening angle, α0 - :attr:`~hmodel.params.Params.alpha0_half_width`
    (:func:`hmodel.cell.bihex.check_params`), is 45°: where an unloaded bi-hexagon's two
    hexagons just touch (that half-width inverted)."""
    if spread <= 0.5:
        return math.radians((45.0 - 30.0 * spread) / (1.0 - spread))
    return math.radians((45.0 + 90.0 * spread) / (1.0 + spread))


_HERTZ = ("shear_modulus", "poisson", "phi_g", "alpha0")

VARIANTS = MappingProxyType({
    "published": ModelVariant("published", "The H-model as published (Nicot & Darve 2011) and its 3D bi-hexagon "
                                           "lift: alpha0 as given, whatever the specimen's density."),
    "density": ModelVariant("density", "The published model with alpha0 set by each specimen's void ratio e0 "
                                       "(the REV's initial volume follows the specimen's, 1 + e0), from the "
                                       "alpha0 calibrated at a reference void ratio e_ref.", uses_e0=True),
    "hertz": ModelVariant("hertz", "The density model with Hertz-Mindlin contacts between the grains (shear "
                                   "modulus and Poisson ratio of the grains in place of kn and kt/kn): "
                                   "stiffness that grows with pressure.", uses_e0=True,
                          options=(("contact", "hertz-mindlin"),), fitted=_HERTZ),
    "rebirth": ModelVariant("rebirth", "The hertz model whose cells are reborn, at contact and force-free, "
                                       "in the space a cell held when its contacts opened.", uses_e0=True,
                            options=(("contact", "hertz-mindlin"), ("renewal", "rebirth")),
                            fitted=_HERTZ),
    "mix": ModelVariant("mix", "The hertz model whose cells are reborn, at contact and force-free, at "
                               "the REV's mean box (renewal=mix): one steady state in 2D, none yet in "
                               "3D (docs/mechanisms.md).", uses_e0=True,
                        options=(("contact", "hertz-mindlin"), ("renewal", "mix")), fitted=_HERTZ),
    "cross": ModelVariant("cross", "The hertz model whose bi-hexagons' two hexagons touch: frictionless "
                                   "contacts between their lateral grains (3D only).", uses_e0=True,
                          options=(("contact", "hertz-mindlin"), ("cross_contacts", "frictionless")),
                          fitted=_HERTZ),
    "axisym": ModelVariant("axisym", "The hertz model whose bi-hexagons follow the lateral strain's mean "
                                     "about their axis (lateral=axisymmetric): a closed cell can follow "
                                     "any strain (in 2D the hertz model).", uses_e0=True,
                           options=(("contact", "hertz-mindlin"), ("lateral", "axisymmetric")),
                           fitted=_HERTZ),
    "axisym-mix": ModelVariant("axisym-mix", "The axisym model whose cells are also reborn at the REV's "
                                             "mean box (renewal=mix; in 2D the mix model).", uses_e0=True,
                               options=(("contact", "hertz-mindlin"), ("renewal", "mix"),
                                        ("lateral", "axisymmetric")), fitted=_HERTZ),
})
#: Other names of variants: the one the docs recommend for sands (docs/mechanisms.md, "Which
#: variant for sands": stiffness that follows pressure as a DEM assembly's, the closest on
#: Karlsruhe fine sand and on the DEM samples, the smallest 3D dilatancy).
ALIASES = MappingProxyType({"sand": "axisym-mix"})


def get_variant(name: str | None) -> ModelVariant:
    """The variant called ``name`` (or an alias; None: the published model)."""
    key = ALIASES.get(name, name) if name is not None else DEFAULT
    if key not in VARIANTS:
        names = ", ".join([*VARIANTS, *(f"{a} (= {v})" for a, v in ALIASES.items())])
        raise InputError(f"no model {name!r} (models: {names})")
    return VARIANTS[key]
