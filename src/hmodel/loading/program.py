"""Loading programs: sequences of stages read from TOML (``hmodel run program``).

A stage is one mixed-control segment (report §1.1.2): three constraint rows, each a strain
change over the stage or a stress target reached linearly over its increments. Rows are named
by what they control::

    eps11 eps22 eps12 eps_v (= eps11 + eps22)     strain changes over the stage
    sig11 sig22 sig12 p (= (sig11 + sig22)/2) q (= sig11 - sig22)   stress targets [Pa]

A stress target is a number in Pa, a text with units or the pressure ``p0`` (``"150kPa"``,
``"0.25 * p0"``) or ``"hold"`` (its value at the start of the stage). ``p0`` is the mean stress
after the latest ``iso`` stage. A stage names its rows in ``control = {...}`` or takes a preset
(``iso``, ``drained``, ``undrained``, ``oedometric``, ``constant_p``, ``proportional``) that
fixes all rows but the one driving it. Stages may be repeated as cycles (``repeat = N`` of a
list of ``stages``) and end early on a criterion (``until = "p <= 0.05 * p0"``), see
``docs/programs.md``.

A program with ``dim = 3`` (or a ``[sphere]`` table: ``order``, ``azimuths``, ``alpha_omega``,
``axis``) runs on the 3D H-model (:class:`~hmodel.rev.rev3d.Rev3D`, axis 1 axial): its stages
name six rows (:data:`~hmodel.loading.stages.ROWS_3D`: also eps33, eps23, eps13, sig33, sig23,
sig13, the lateral differences ``eps22-eps33`` and ``sig22-sig33``, the radial stress ``sig_r``
= (σ22 + σ33)/2, and ``b``; p = tr σ/3,
q = σ11 - (σ22 + σ33)/2, eps_v = tr ε) and take the presets of
:data:`~hmodel.loading.stages.PRESETS_3D` (also ``true_triaxial``).

A program runs one material point; ``result.csv`` gets the columns of every path plus
``cycle`` (0 outside cycles), and ``stage`` holds the stage's name.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..cell import CellSolver
from ..errors import InputError, SolverError
from ..limits import check_count, check_rows
from ..params import Params
from ..rev import Rev, RevState
from ..rev.model3d import assignments_3d, check_3d_params
from ..rev.rev3d import Rev3D
from ..rev.sphere import Sphere
from .control import Tangent
from .expressions import MAX_LENGTH, Criterion, Expression
from .named_paths import ISO_STEP, consolidate
from .newton import NewtonSettings
from .result import PathResult, Recorder, columns_for
from .segment import StageFailed, run_segment
from .stages import (
    ROWS,
    ROWS_3D,
    Stage,
    check_b,
    component_order,
    components_for,
    is_stress_row,
    presets_for,
    row_coefficients,
    rows_for,
)

#: Columns a criterion may compare (those of the result table that are numbers), by the
#: number of components (2D: 3, 3D: 6).
CRITERION_COLUMNS_BY_N = {n: tuple(c for c in columns_for(n) if c not in ("point", "stage", "step"))
                          for n in (3, 6)}
#: Columns a criterion of a 2D program may compare.
CRITERION_COLUMNS = CRITERION_COLUMNS_BY_N[3]
_SPHERE_KEYS = {"order": "order", "azimuths": "n_azimuth", "alpha_omega": "alpha_omega", "axis": "axis"}
_STAGE_KEYS = {"name", "preset", "control", "steps", "max_increment", "until", "stop_on_failure"}
_BLOCK_KEYS = {"name", "repeat", "stages", "until", "stop_on_failure"}
#: Longest name, key or other text of a program file: a stage's name is written on every row of
#: its result table (and a program's in its messages), and no name needs more.
MAX_TEXT = 200
#: Longest ``description`` of a program (a paragraph; it is read by people only).
MAX_DESCRIPTION = 2000
#: Keys whose text values are expressions (rows and criteria), whose own limit is
#: :data:`~hmodel.loading.expressions.MAX_LENGTH`.
_EXPRESSION_KEYS = {"until", *ROWS, *ROWS_3D}
#: Largest program file read, in characters: a program is text written or generated for a
#: person to read; this bounds what parsing a file (or a device such as /dev/zero) may take.
MAX_FILE_CHARS = 10**7


@dataclass(frozen=True)
class Block:
    """``repeat`` cycles of ``stages``, ending early when ``until`` is met."""

    name: str
    stages: tuple[Stage, ...]
    repeat: int = 1
    until: Criterion | None = None
    stop_on_failure: bool = False


@dataclass(frozen=True)
class Program:
    """A loading program: blocks of stages (a single stage is a block of one, not a cycle)."""

    name: str
    blocks: tuple[Block, ...]
    params: Mapping[str, str] = field(default_factory=dict)
    #: the 3D H-model's sphere (directions, azimuths, fabric) of a program with ``dim = 3``;
    #: None: a 2D program
    sphere: Sphere | None = None
    #: the name of the file the program was read from ("" when built in Python); figures' titles
    file: str = ""

    @property
    def dim(self) -> int:
        """2 or 3: the H-model the program runs on."""
        return 2 if self.sphere is None else 3

    # ------------------------------------------------------------------ reading

    @classmethod
    def from_toml(cls, path: "str | Path") -> "Program":
        """Read a program file (see ``docs/programs.md``)."""
        path = Path(path)
        try:
            with open(path, encoding="utf-8") as fh:
                text = fh.read(MAX_FILE_CHARS + 1)
            if len(text) > MAX_FILE_CHARS:
                raise InputError(f"program {str(path)!r} is longer than {MAX_FILE_CHARS:,} characters, "
                                 f"the most a program file may have")
            data = tomllib.loads(text)
        except OSError as e:
            raise InputError(f"cannot read program {str(path)!r}: {e.strerror}") from None
        except UnicodeDecodeError as e:
            raise InputError(f"program {str(path)!r} is not UTF-8 text (byte {e.start}: "
                             f"{e.object[e.start:e.start + 1]!r})") from None
        except tomllib.TOMLDecodeError as e:
            raise InputError(f"program {str(path)!r} is not valid TOML: {e}") from None
        return replace(cls.from_dict(data, default_name=path.stem), file=path.name)

    @classmethod
    def from_dict(cls, data: Mapping, default_name: str = "program") -> "Program":
        """A program from the tables of a TOML file: ``name``, ``params`` and ``stage`` (a list)."""
        _check_text(data, "program")
        _keys(data, {"name", "description", "params", "stage", "dim", "sphere"}, "program")
        sphere = _sphere(data)
        n = 3 if sphere is None else 6
        stages = data.get("stage")
        if not isinstance(stages, list) or not stages:
            raise InputError("a program needs at least one [[stage]]")
        params = data.get("params", {})
        if not isinstance(params, Mapping):
            raise InputError("[params] must be a table of parameter values")
        blocks = []
        for i, item in enumerate(stages, 1):
            if not isinstance(item, Mapping):
                raise InputError(f"stage {i} must be a table")
            blocks.append(_block(item, i, n) if "stages" in item or "repeat" in item
                          else Block(_label(item, i), (_stage(item, _label(item, i), n),)))
        _check_p0_targets(blocks)
        if sphere is not None:
            check_3d_params([str(k) for k in params], "[params] of a 3D program")
        name = _name(data["name"], "program: name") if "name" in data else default_name
        program = cls(name, tuple(blocks), {str(k): _name(v, f"[params] {k}") for k, v in params.items()},
                      sphere)
        check_count(program.n_increments, "increments of the program")
        # a row per increment (an iso stage's consolidation counted as its final row)
        check_rows(program.n_increments, "the program's increments")
        return program

    def with_params(self, assignments: Sequence[str] | None, base: Params | None = None,
                    solver: CellSolver | None = None) -> Params:
        """The program's ``[params]`` overridden by ``NAME=VALUE`` assignments (``-p``), on
        ``base`` (default: the defaults; a calibrated model's parameters). A 3D program refuses
        the 2D model's own parameters (n_theta, alpha_omega, beta_omega) and, where neither its
        ``[params]``, the assignments nor a ``base`` set ``sliding_rhs``, takes the 3D model's
        (``equilibrium``, or the one the learned cell of ``solver`` was trained with:
        :func:`~hmodel.rev.model3d.assignments_3d`), as ``hmodel run triaxial`` does."""
        given = [f"{k}={v}" for k, v in self.params.items()]
        if self.sphere is None:
            return Params.parse_assignments(given + list(assignments or []), base)
        check_3d_params([a.partition("=")[0].strip() for a in assignments or []],
                        "--param of a 3D program")
        return Params.parse_assignments(assignments_3d(given + list(assignments or []), solver, base,
                                                       "[params] of a 3D program"), base)

    @property
    def n_increments(self) -> int:
        """Increments of the whole program if no criterion ends anything early (iso stages
        counted as one)."""
        return sum(b.repeat * sum(1 if s.iso else s.n_steps() for s in b.stages) for b in self.blocks)

    # ------------------------------------------------------------------ running

    def run(self, params: Params | None, solver: CellSolver | None = None, progress=None,
            chunk: Callable[[RevState, int], int] | None = None,
            settings: NewtonSettings = NewtonSettings()) -> PathResult:
        """Run the program on one material point of ``params``; returns the table of every state.

        ``params`` is used as given (in 3D too: ``Params()`` is the report's λ); None: the
        program's own, :meth:`with_params` (the 3D model's defaults in a 3D program).
        ``solver``: the cell solver (None: the closed form); in a 3D program a 2D H-cell solver
        steps the hexagons of every bi-hexagon (:func:`~hmodel.rev.model3d.cell_solver_3d`).

        ``meta["stopped"]`` lists the criteria that ended stages or cycles early (stage, cycle,
        criterion). An increment that cannot be solved raises :class:`ProgramFailed`, whose
        ``result`` holds every state before it. ``chunk``: see
        :func:`~hmodel.loading.segment.run_segment` (stability probes between chunks).
        ``settings``: the mixed-control Newton's (e.g. ``max_events``, the cell events one
        increment may commit before it is refused).
        """
        if params is None:
            params = self.with_params(None, solver=solver)
        if not isinstance(params, Params):
            raise InputError("a program runs one material point: give one parameter set")
        rev = self.make_rev(params, solver)
        rev.check_size(1, rows=self.n_increments, columns=len(columns_for(rev.n_components)) + 1)
        meta = {"test": "program", "program": self.name, "file": self.file, "params": params.to_dict(), "dim": self.dim,
                "solver": rev.solver.name, "stopped": [], "cycles": {},
                "undrained_stages": self.undrained_stages}
        if self.sphere is not None:
            meta["sphere"] = {"order": self.sphere.order, "n_azimuth": self.sphere.n_azimuth,
                              "alpha_omega": self.sphere.alpha_omega, "axis": list(self.sphere.axis)}
        rec = Recorder(meta, rev.solver_fractions)
        rec.tags["cycle"] = 0
        run = _Run(rev, rec, progress, self.n_increments, chunk, settings)
        try:
            for block in self.blocks:
                run.block(block)
        except _Stopped:
            pass
        except StageFailed as e:
            rec.meta["p0"] = [run.p0] if run.p0 is not None else None
            raise ProgramFailed(str(e), rec.result()) from None
        rec.meta["p0"] = [run.p0] if run.p0 is not None else None
        return rec.result()

    def make_rev(self, params: Params, solver: CellSolver | None = None) -> Rev | Rev3D:
        """The REV the program runs on (also the stability probes' REV, :mod:`hmodel.stability`):
        a 2D :class:`Rev`, or for ``dim = 3`` a :class:`Rev3D` of the program's sphere, whose
        bi-hexagons a 2D H-cell ``solver`` steps (the closed form's: the closed-form bi-hexagon)."""
        if self.sphere is None:
            return Rev(params, solver)
        return Rev3D(params, self.sphere, solver)

    @property
    def undrained_stages(self) -> list[str]:
        """Names of the stages at constant volume (an ``eps_v = 0`` row): their excess pore
        pressure is p0 − p (the total mean stress stays p0 when the water carries the rest)."""
        return sorted({s.name for b in self.blocks for s in b.stages if s.rows.get("eps_v") == 0.0})


class ProgramFailed(SolverError):
    """A program stopped on an increment it could not solve; ``result`` holds every state
    computed before it."""

    def __init__(self, message: str, result: PathResult):
        super().__init__(message)
        self.result = result


class _Stopped(Exception):
    """Ends a program on an unsolvable increment of a stage with ``stop_on_failure``."""


class _Run:
    """The running state of a program: REV state, p0, the recorder, progress."""

    def __init__(self, rev, rec, progress, total, chunk, settings):
        self.rev, self.rec, self.progress, self.total, self.chunk = rev, rec, progress, max(total, 1), chunk
        self.settings = settings
        self.state = rev.initial(1)
        self.p0: float | None = None
        self.done = 0
        self.tangent = Tangent()
        self.block_name = ""

    def advance(self, n: int) -> None:
        self.done += n
        if self.progress is not None:
            self.progress(min(1.0, self.done / self.total))

    def block(self, block: Block) -> None:
        self.block_name = block.name
        cycles = block.repeat > 1 or block.until is not None
        for c in range(1, block.repeat + 1):
            self.rec.tags["cycle"] = c if cycles else 0
            for stage in block.stages:
                met = self.stage(stage, block.until, c if cycles else 0,
                                 stage.stop_on_failure or block.stop_on_failure)
                if met is not None and met is block.until:
                    self.rec.meta["stopped"].append({"stage": stage.name, "cycle": c, "until": met.text})
                    self.rec.meta["cycles"][block.name] = c
                    return
        if cycles:
            self.rec.meta["cycles"][block.name] = block.repeat
        self.rec.tags["cycle"] = 0

    def stage(self, stage: Stage, block_until: Criterion | None, cycle: int, stop_on_failure: bool):
        """Run one stage; returns the criterion that ended it early (None: ran through)."""
        if stage.iso is not None:
            self.state = consolidate(self.rev, [stage.iso], state=self.state,
                                     step=stage.max_increment or ISO_STEP, recorder=self.rec)
            self.p0 = float(self.state.p[0])
            self.tangent = Tangent()
            self.advance(1)
            if self.chunk is not None:
                self.chunk(self.state, 0)
            return None
        seg = stage.segment(self.state, self.p0)
        criteria = [c for c in (stage.until, block_until) if c is not None]
        env = {"p0": self.p0 if self.p0 is not None else float("nan")}
        for c in criteria:
            if "p0" in c.names and self.p0 is None:
                raise InputError(f"stage {stage.name!r}: until {c.text!r} uses p0, but no iso stage "
                                 f"comes before it")

        def stop(cols):
            hits = [c({**cols, **env}) for c in criteria]
            return np.logical_or.reduce(hits) if hits else None

        label = stage.name if not cycle else f"{stage.name} (cycle {cycle})"
        first = self.done

        def progress(fraction):
            self.advance(first + round(fraction * seg.n_steps) - self.done)
        try:
            out = run_segment(self.rev, self.state, seg, self.rec, stop=stop if criteria else None,
                              chunk=self.chunk, progress=progress, tangent=self.tangent,
                              settings=self.settings)
        except StageFailed as e:
            rows = ", ".join(f"{n} = {v:.6g}" for n, v, s in zip(component_order(list(stage.rows)), seg.values,
                                                              seg.stress_rows) if s)
            why = (f"increment {e.increment} of {seg.n_steps}: the targets ({rows or 'strain rows only'}) "
                   f"cannot be reached: {e}")
            if not stop_on_failure:
                raise StageFailed(f"stage {label!r}, {why}", e.increment) from None
            self.rec.meta["stopped"].append({"stage": stage.name, "cycle": cycle,
                                             "increment": e.increment, "failure": why})
            if cycle:
                self.rec.meta["cycles"][self.block_name] = cycle
            raise _Stopped() from None
        self.state = out.state
        if out.met is None:
            return None
        met = next(c for c in criteria if c({**out.met, **env})[-1])
        if met is stage.until:
            self.rec.meta["stopped"].append({"stage": stage.name, "cycle": cycle, "until": met.text})
        return met


# ---------------------------------------------------------------------- parsing helpers

def _check_p0_targets(blocks: list[Block]) -> None:
    """Refuse a stage whose targets or criteria use p0 before any iso stage has set it, and a
    stress target that is not finite at the p0 of the iso stage before it (``p0 / 0``)."""
    p0 = None
    for block in blocks:
        for stage in block.stages:
            if stage.iso is not None:
                p0 = stage.iso
                continue
            uses = [v.text for v in stage.rows.values() if isinstance(v, Expression) and "p0" in v.names]
            uses += [c.text for c in (stage.until, block.until) if c is not None and "p0" in c.names]
            if uses and p0 is None:
                raise InputError(f"stage {stage.name!r}: {uses[0]!r} uses p0, but no iso stage comes "
                                 f"before it")
            for name, v in stage.rows.items():
                if isinstance(v, Expression):
                    stage.target(name, v, p0)


def _keys(table: Mapping, allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(sorted(allowed))})")


def _check_text(value, where: str, limit: int = MAX_TEXT) -> None:
    """Refuse a key or text of a program's tables longer than :data:`MAX_TEXT` (an
    expression's: :data:`~hmodel.loading.expressions.MAX_LENGTH`), before any is read or named
    in a message."""
    if isinstance(value, str):
        if len(value) > limit:
            kind = {MAX_LENGTH: "an expression", MAX_DESCRIPTION: "a description"}.get(
                limit, "a name or text of a program")
            raise InputError(f"{where} is {len(value):,} characters long; {kind} has at most {limit}")
    elif isinstance(value, Mapping):
        expressions = where.endswith("control")
        for key, item in value.items():
            if len(str(key)) > MAX_TEXT:
                raise InputError(f"a key of {where} is {len(str(key)):,} characters long; a name or "
                                 f"text of a program has at most {MAX_TEXT}")
            limit = (MAX_LENGTH if expressions or key in _EXPRESSION_KEYS else
                     MAX_DESCRIPTION if key == "description" and where == "program" else MAX_TEXT)
            # the path to the text, its last steps only (each key is short by now)
            _check_text(item, key if where == "program" or len(where) > MAX_TEXT else f"{where}: {key}",
                        limit)
    elif isinstance(value, list):
        for i, item in enumerate(value, 1):
            _check_text(item, f"{where} {i}" if len(where) <= MAX_TEXT else where, limit)


def _name(value, where: str) -> str:
    """A name of a program (any TOML value, as text) of at most :data:`MAX_TEXT` characters."""
    text = str(value)
    if len(text) > MAX_TEXT:
        raise InputError(f"{where} is {len(text):,} characters long; a name or text of a program "
                         f"has at most {MAX_TEXT}")
    return text


def _label(item: Mapping, i: int) -> str:
    name = item.get("name", item.get("preset", f"stage {i}"))
    return _name(name, f"stage {i}: name") if name else f"stage {i}"


def _positive_int(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InputError(f"{what} must be a positive integer, got {value!r}")
    return value


def _criterion(text, where: str, n: int = 3) -> Criterion | None:
    if text is None:
        return None
    return Criterion.parse(text, CRITERION_COLUMNS_BY_N[n], ("p0",), what=f"{where}: until")


def _sphere(data: Mapping) -> Sphere | None:
    """The sphere of a 3D program (``dim = 3`` and/or a ``[sphere]`` table), None for 2D."""
    dim = data.get("dim", 3 if "sphere" in data else 2)
    if isinstance(dim, bool) or dim not in (2, 3):
        raise InputError(f"program: dim must be 2 (hexagons in the plane) or 3 (bi-hexagons on the "
                         f"sphere), got {dim!r}")
    table = data.get("sphere", {})
    if not isinstance(table, Mapping):
        raise InputError("[sphere] must be a table (order, azimuths, alpha_omega, axis)")
    if dim == 2:
        if "sphere" in data:
            raise InputError("program: a [sphere] table is the 3D H-model's, and dim = 2")
        return None
    _keys(table, set(_SPHERE_KEYS), "[sphere]")
    for key, value in table.items():
        ok = (isinstance(value, list) and len(value) == 3 and all(_number(x) for x in value)
              if key == "axis" else _number(value))
        if not ok:
            raise InputError(f"[sphere] {key} must be {'3 numbers' if key == 'axis' else 'a number'}, "
                             f"got {value!r}")
    return Sphere(**{_SPHERE_KEYS[k]: (tuple(v) if k == "axis" else v) for k, v in table.items()})


def _block(item: Mapping, i: int, n: int = 3) -> Block:
    name = _label(item, i)
    where = f"stage {name!r}"
    _keys(item, _BLOCK_KEYS, where)
    repeat = _positive_int(item.get("repeat", 1), f"{where}: repeat (the cycle count)")
    stages = item.get("stages")
    if not isinstance(stages, list) or not stages or not all(isinstance(s, Mapping) for s in stages):
        raise InputError(f"{where}: stages must be a non-empty list of stage tables")
    parsed = []
    for j, s in enumerate(stages, 1):
        if "stages" in s or "repeat" in s:
            raise InputError(f"{where}: cycles cannot be nested")
        parsed.append(_stage(s, _label(s, j), n))
        if parsed[-1].iso is not None and repeat > 1:
            raise InputError(f"{where}: an iso stage cannot be repeated")
    return Block(name, tuple(parsed), repeat, _criterion(item.get("until"), where, n),
                 _flag(item, "stop_on_failure", where))


def _stage(item: Mapping, name: str, n: int = 3) -> Stage:
    where = f"stage {name!r}"
    preset = item.get("preset")
    if preset is not None and not isinstance(preset, str):
        raise InputError(f"{where}: preset must be a name, got {preset!r}")
    steps = item.get("steps")
    if steps is not None:
        steps = check_count(_positive_int(steps, f"{where}: steps"), f"{where}: steps")
    max_inc = item.get("max_increment")
    if max_inc is not None and (isinstance(max_inc, bool) or not isinstance(max_inc, (int, float))
                                or not (math.isfinite(max_inc) and max_inc > 0)):
        raise InputError(f"{where}: max_increment must be a positive number, got {max_inc!r}")
    if steps is not None and max_inc is not None:
        raise InputError(f"{where}: give steps or max_increment, not both")
    until = _criterion(item.get("until"), where, n)
    common = dict(name=name, steps=steps, max_increment=max_inc, until=until,
                  stop_on_failure=_flag(item, "stop_on_failure", where))
    if preset is None:
        _keys(item, _STAGE_KEYS, where)
        control = item.get("control")
        if not isinstance(control, Mapping):
            example = ("eps11 = 0.02, sig22 = \"hold\", eps12 = 0" if n == 3 else
                       "eps11 = 0.02, sig22 = \"hold\", sig33 = \"hold\", eps23 = 0, eps13 = 0, eps12 = 0")
            raise InputError(f"{where}: needs a preset or a control table, e.g. control = {{{example}}}")
        return Stage(rows=_rows(control, where, n), **common)
    if preset == "iso":
        _keys(item, {"name", "preset", "p", "max_increment"}, where)
        return Stage(name=name, iso=_pressure(item.get("p"), f"{where}: p"), max_increment=max_inc)
    if preset == "proportional":
        _keys(item, (_STAGE_KEYS - {"control"}) | {"direction", "magnitude"}, where)
        d = item.get("direction")
        m = item.get("magnitude")
        names = ("eps11", "eps22", "eps12") if n == 3 else ("eps11", "eps22", "eps33", "eps12", "eps13", "eps23")
        if not (isinstance(d, list) and len(d) == n and all(_number(x) for x in d) and any(d)):
            raise InputError(f"{where}: direction must be {n} numbers ({', '.join(names)}), not all zero")
        if not (_number(m) and m > 0):
            raise InputError(f"{where}: magnitude must be a positive strain, got {m!r}")
        d = np.asarray(d, float) * m / np.linalg.norm(d)
        return Stage(rows=dict(zip(names, map(float, d))), **common)
    presets = presets_for(n)
    if preset not in presets:
        other = presets_for(6 if n == 3 else 3)
        hint = (f"; {preset!r} is a {'3D' if n == 3 else '2D'} preset" if preset in other else "")
        raise InputError(f"{where}: unknown preset {preset!r} (presets: iso, "
                         f"{', '.join(presets)}, proportional){hint}")
    fixed, drivers = presets[preset]
    _keys(item, (_STAGE_KEYS - {"control"}) | set(fixed) | set(drivers), where)
    given = [k for k in drivers if k in item]
    if len(given) != 1:
        raise InputError(f"{where}: preset {preset!r} is driven by exactly one of "
                         f"{', '.join(drivers)}, got {', '.join(given) or 'none'}")
    rows = {**fixed, **{k: item[k] for k in fixed if k in item}, given[0]: item[given[0]]}
    return Stage(rows=_rows(rows, where, n), **common)


def _flag(item: Mapping, key: str, where: str) -> bool:
    value = item.get(key, False)
    if not isinstance(value, bool):
        raise InputError(f"{where}: {key} must be true or false, got {value!r}")
    return value


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _pressure(value, what: str) -> float:
    if _number(value) and value > 0:
        return float(value)
    if isinstance(value, str):
        v = Expression.parse(value, (), what)({})
        if _number(v) and v > 0:
            return float(v)
    raise InputError(f"{what} must be a positive pressure (a number in Pa or e.g. \"200kPa\"), got {value!r}")


def _rows(control: Mapping, where: str, n: int = 3) -> dict[str, object]:
    """Check the rows of a control table (three in 2D, six in 3D) and read their values."""
    table, component, dim = rows_for(n), components_for(n), ("2D" if n == 3 else "3D")
    unknown = [k for k in control if k not in table]
    if unknown:
        other = rows_for(6 if n == 3 else 3)
        hint = ("; a 3D row: a 3D program says dim = 3" if n == 3 and unknown[0] in other else "")
        raise InputError(f"{where}: unknown component {unknown[0]!r} (components: {', '.join(table)})"
                         f"{hint}")
    seen: dict[str, str] = {}
    for name in control:
        comp = component.get(name)
        if comp is not None:
            if comp in seen:
                raise InputError(f"{where}: component {comp} is controlled twice ({seen[comp]} and {name})")
            seen[comp] = name
    shears = ("12",) if n == 3 else ("23", "13", "12")
    for comp in shears:
        if comp not in seen:
            raise InputError(f"{where}: component {comp} is not controlled (give eps{comp} or sig{comp})")
    if len(control) != n:
        normal = ("11", "22") if n == 3 else ("11", "22", "33")
        free = [c for c in normal if c not in seen]
        words = "three" if n == 3 else "six"
        comps = "11, 22, 12" if n == 3 else "11, 22, 33, 23, 13, 12"
        raise InputError(f"{where}: {len(control)} rows control the components; give exactly {words} "
                         f"({'' if n == 3 else dim + ': '}components {comps}"
                         f"{'; not controlled: ' + ', '.join(free) if len(control) < n else ''})")
    if "b" in control:
        check_b(control["b"], f"{where}: b")
    M = np.array([row_coefficients(k, control[k], n) for k in control], float)
    if abs(np.linalg.det(M)) < 1e-12:
        raise InputError(f"{where}: rows {', '.join(control)} do not fix every component "
                         f"(they are linearly dependent)")
    rows: dict[str, object] = {}
    for name, value in control.items():
        stress = is_stress_row(name)
        if name == "b":
            rows[name] = float(value)
        elif not stress:
            if not _number(value):
                raise InputError(f"{where}: {name} must be a strain change (a number), got {value!r}")
            rows[name] = float(value)
        elif value == "hold":
            rows[name] = "hold"
        elif _number(value):
            rows[name] = float(value)
        elif isinstance(value, str):
            rows[name] = Expression.parse(value, ("p0",), f"{where}: {name}")
        else:
            raise InputError(f"{where}: {name} must be a stress target (Pa, \"150kPa\", \"0.3 * p0\" "
                             f"or \"hold\"), got {value!r}")
    return rows


def cycle_summary(result: PathResult) -> list[dict]:
    """Per cycle of a program's result: the least mean stress (and over p0), the largest
    excess pore pressure p0 − p, and the double-amplitude axial strain (max − min of eps11
    within the cycle), the usual measures of cyclic liquefaction."""
    if "cycle" not in result.columns:
        return []
    p0 = (result.meta.get("p0") or [float("nan")])[0]
    c = result["cycle"]
    rows = []
    for k in np.unique(c[c > 0]):
        m = c == k
        p = result["p"][m]
        rows.append({"cycle": int(k), "p_min": float(p.min()), "p_min_over_p0": float(p.min() / p0),
                     "excess_pore_pressure_max": float(p0 - p.min()),
                     "double_amplitude_eps11": float(np.ptp(result["eps11"][m]))})
    return rows
