"""Cells that are reborn: the ``renewal="rebirth"`` mechanism (docs/mechanisms.md, "Renewal").

In the published H-model a cell whose contact opens (d > 2r, or a contact that would pull)
carries no force from then on (report Fig. 1.5) and, under monotonic loading, never again: at
the end of a drained triaxial test most of the REV's cells are such empty frames. In a granular
assembly the grains of a broken mesostructure do not vanish: they rearrange and form a new
structure in the space the old one held. The rebirth mechanism says so at the cell's scale:

- a cell that opens in an increment is replaced, at the end of that increment, by a new cell of
  the same direction, at contact (d1 = d2 = 2r), force-free, whose initial volume equals the
  volume the broken cell held (the polygon of its six grain centres, eq. 1.20's hexagon volume);
- the new cell's opening angle α_r follows from that volume on the branch of unloaded cells
  between the densest (2D: α = 30°, where grains 2-6 touch; 3D: α = 45°, where the grains of the
  two hexagons touch) and the loosest (2D: 60°; 3D: arccos 1/3 = 70.5°), the same branch
  :mod:`hmodel.rev.density` maps void ratios on;
- a cell whose space is looser than the loosest cell holds no structure: it stays open (as
  published) and is reborn in a later increment once its space has shrunk back.

No parameter is added: the mechanism reads the cell's own state. The force-free rebirth keeps
the REV's stress continuous (the broken cell carried nothing); the rebirth conserves the cell's
volume, so the REV's volume is that of its strain, as before. In 3D the bi-hexagon is reborn as
a whole (its two hexagons share grains 1 and 4, and their common l1) once both hexagons are
open: a hexagon that still carries keeps its forces.

``renewal="mix"`` reborn an opened H-cell (a bi-hexagon both of whose hexagons opened) at the
REV's mean box instead (:func:`mix_angle`, :func:`mix_rebirth`, :func:`mix_rebirth_bihex`): a REV
quantity, so the REV applies it (:mod:`hmodel.rev.kernels`, :mod:`hmodel.rev.kernels3d`), not
the cell's own increment.
"""

from __future__ import annotations

import math

from numba import njit

#: Values of the packed ``P_RENEW`` entry: no renewal, the 2D H-cell's rebirth, the bi-hexagon's,
#: the 2D rebirth at the REV's mean box area (applied by the REV: :mod:`hmodel.rev.kernels`).
RENEW_NONE, RENEW_CELL, RENEW_BIHEX, RENEW_MIX = 0.0, 1.0, 2.0, 3.0
#: ``Params.renewal`` -> packed value of a 2D cell (the bi-hexagon's kernel_params turns
#: ``rebirth`` into :data:`RENEW_BIHEX`).
RENEW_CODES = {"none": RENEW_NONE, "rebirth": RENEW_CELL, "mix": RENEW_MIX}
#: The neutral angles α_n where an unloaded cell's box is largest: 2D cos α_n = (√33 - 1)/8
#: (53.6°, the box l1·l2), 3D cos α_n = (√13 - 1)/6 (64.3°, the bi-hexagon's l1·l2·l3).
NEUTRAL_2D = math.acos((math.sqrt(33.0) - 1.0) / 8.0)
NEUTRAL_3D = math.acos((math.sqrt(13.0) - 1.0) / 6.0)
#: The branch of unloaded cells a reborn cell's opening angle lies on, (densest, loosest) [rad].
BRANCH_2D = (math.pi / 6.0, math.pi / 3.0)
BRANCH_3D = (math.pi / 4.0, math.acos(1.0 / 3.0))


@njit(cache=True, inline="always", error_model="numpy")
def hexagon_volume(d1, d2, a):
    """Area of a hexagon's six grain centres (d2 + d1 cos α)·2 d1 sin α (eq. 1.20)."""
    return (d2 + d1 * math.cos(a)) * 2.0 * d1 * math.sin(a)


@njit(cache=True, inline="always", error_model="numpy")
def unloaded_volume(a, two_r, dim):
    """Volume of an unloaded cell (d1 = d2 = 2r) at opening angle α: 2D 2r²(1 + cos α)·2 sin α,
    3D the bi-hexagon's l1*·l2*·l3* = 2r(1 + cos α)·(2·2r sin α)²."""
    s = math.sin(a)
    if dim == 2:
        return two_r * two_r * (1.0 + math.cos(a)) * 2.0 * s
    return two_r * (1.0 + math.cos(a)) * 4.0 * two_r * two_r * s * s


@njit(cache=True, error_model="numpy")
def rebirth_angle(volume, two_r, dim):
    """Opening angle of the unloaded cell of ``volume`` on the branch (:data:`BRANCH_2D` /
    :data:`BRANCH_3D`), where the volume rises with α; the densest angle below the branch, and
    -1.0 above it (no cell fits: the space is looser than the loosest cell)."""
    lo, hi = (BRANCH_2D if dim == 2 else BRANCH_3D)
    top = unloaded_volume(hi, two_r, dim)
    if volume > top * (1.0 + 1e-12):  # round-off at the flat top is the loosest cell
        return -1.0
    if volume >= top:
        return hi
    if volume <= unloaded_volume(lo, two_r, dim):
        return lo
    for _ in range(60):  # bisection: the volume is monotonic on the branch
        mid = 0.5 * (lo + hi)
        if unloaded_volume(mid, two_r, dim) < volume:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True, error_model="numpy")  # a call, not inlined: keeps the linear path lean
def reborn_cell(d1, d2, a, two_r):
    """The 2D rebirth of a cell that opened at (d1, d2, α): ``(reborn, d1, d2, α, l1, l2)`` of the
    new cell at contact (eq. 1.2 with d1 = d2 = 2r), or ``reborn`` False when its space holds no
    cell."""
    ar = rebirth_angle(hexagon_volume(d1, d2, a), two_r, 2)
    if ar < 0.0:
        return False, d1, d2, a, 0.0, 0.0
    return True, two_r, two_r, ar, two_r * (1.0 + 2.0 * math.cos(ar)), 2.0 * two_r * math.sin(ar)


@njit(cache=True, inline="always", error_model="numpy")
def bihex_open(flags, i):
    """Whether both hexagons of bi-hexagon ``i`` are open (``flags[i]``: open1, open2 at 1, 2
    and 6, 7): a rebirth then loses no force."""
    return (flags[i, 1] or flags[i, 2]) and (flags[i, 6] or flags[i, 7])


@njit(cache=True, error_model="numpy")  # a call, not inlined: keeps the linear path lean
def renew_bihex(out, flags, i, two_r):
    """Rebirth of bi-hexagon ``out[i]`` (16 fields, just advanced) when both hexagons are open
    (:func:`bihex_open`), so that no force is lost: both hexagons at contact, force-free, at the
    angle whose unloaded bi-hexagon has the broken one's volume l1*·l2*·l3*
    (:func:`hmodel.cell.bihex.bihex_volume`, ``hexagon``); left as it is when no cell fits."""
    if not bihex_open(flags, i):
        return
    l1s = 0.5 * (out[i, 1] + out[i, 0] * math.cos(out[i, 2]) + out[i, 9]
                 + out[i, 8] * math.cos(out[i, 10]))
    volume = l1s * 2.0 * out[i, 0] * math.sin(out[i, 2]) * 2.0 * out[i, 8] * math.sin(out[i, 10])
    ar = rebirth_angle(volume, two_r, 3)
    if ar >= 0.0:
        reborn_bihex(out, flags, i, ar, two_r)


@njit(cache=True, error_model="numpy")  # a call, not inlined: keeps the trial's loop lean
def mix_rebirth_bihex(out, flags, i, area, compressed, two_r):
    """``renewal="mix"`` of bi-hexagon ``out[i]`` when both hexagons are open
    (:func:`bihex_open`): both at contact, force-free, at :func:`mix_angle` of the REV's mean
    box l1·l2·l3 ``area`` on the branch its axis takes (``compressed``: l1 shortened)."""
    if bihex_open(flags, i):
        reborn_bihex(out, flags, i, mix_angle(area, compressed, two_r, 3), two_r)


@njit(cache=True, inline="always", error_model="numpy")
def reborn_bihex(out, flags, i, ar, two_r):
    """Bi-hexagon ``out[i]``'s two hexagons at contact, force-free, at opening angle ``ar``
    (:func:`reborn_hexagon`, A's fields and flags at 0, B's at 8 and 5)."""
    reborn_hexagon(out, flags, i, 0, 0, ar, two_r)
    reborn_hexagon(out, flags, i, 8, 5, ar, two_r)


@njit(cache=True, inline="always", error_model="numpy")
def reborn_hexagon(out, flags, i, k, f, ar, two_r):
    """The hexagon of fields ``out[i, k:k + 8]`` and flags ``flags[i, f:f + 5]`` at contact,
    force-free, at opening angle ``ar`` (eq. 1.2); its open flags stay (the event happened in
    this increment), and it neither slides nor touches beyond its hexagon."""
    l1 = two_r * (1.0 + 2.0 * math.cos(ar))
    l2 = 2.0 * two_r * math.sin(ar)
    out[i, k] = two_r
    out[i, k + 1] = two_r
    out[i, k + 2] = ar
    out[i, k + 3] = 0.0
    out[i, k + 4] = 0.0
    out[i, k + 5] = 0.0
    out[i, k + 6] = l1
    out[i, k + 7] = l2
    flags[i, f] = False
    flags[i, f + 3] = l1 <= two_r
    flags[i, f + 4] = l2 <= two_r


@njit(cache=True, inline="always", error_model="numpy")
def box_at_contact(a, two_r, dim):
    """Box of an unloaded cell (d1 = d2 = 2r) at opening angle α (eq. 1.2): 2D the H-cell's
    l1·l2 = 2r(1 + 2 cos α)·2·2r sin α, 3D the bi-hexagon's l1·l2·l3 = 2r(1 + 2 cos α)·(2·2r sin α)²."""
    l2 = 2.0 * two_r * math.sin(a)
    box = two_r * (1.0 + 2.0 * math.cos(a)) * l2
    return box if dim == 2 else box * l2


@njit(cache=True, error_model="numpy")
def mix_angle(area, compressed, two_r, dim):
    """Opening angle of the unloaded cell whose box is ``area`` (:func:`box_at_contact`,
    ``renewal="mix"``), on the branch where a cell carries: below the neutral angle (the largest
    box: :data:`NEUTRAL_2D`, :data:`NEUTRAL_3D`) for a cell whose axis is being shortened
    (``compressed``), above it otherwise, within the unloaded cells' branch (:data:`BRANCH_2D`,
    :data:`BRANCH_3D`); the neutral angle where the area exceeds every cell's."""
    neutral = NEUTRAL_2D if dim == 2 else NEUTRAL_3D
    first, last = BRANCH_2D if dim == 2 else BRANCH_3D
    if area >= box_at_contact(neutral, two_r, dim):
        return neutral
    lo, hi = (first, neutral) if compressed else (neutral, last)
    end = lo if compressed else hi  # the branch's end away from the neutral angle
    if area <= box_at_contact(end, two_r, dim):
        return end
    for _ in range(60):  # bisection: the box grows towards the neutral angle on either branch
        mid = 0.5 * (lo + hi)
        if (box_at_contact(mid, two_r, dim) < area) == compressed:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True, error_model="numpy")  # a call, not inlined: keeps the trial's loop lean
def mix_rebirth(out, flags, i, area, compressed, two_r):
    """Rebirth of H-cell ``out[i]`` (8 fields), which opened in the increment (``renewal="mix"``,
    docs/mechanisms.md): at contact, force-free (:func:`reborn_hexagon`), at :func:`mix_angle`
    of the REV's mean box area ``area``."""
    reborn_hexagon(out, flags, i, 0, 0, mix_angle(area, compressed, two_r, 2), two_r)
