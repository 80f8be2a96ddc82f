"""Every ``hmodel`` command that README.md and the documentation's pages show runs as written,
against the data hmodel ships (``example:kfs``, ``benchmarks/calibration/dem_sample/``, ...).

Which commands count:

- the pages: README.md and ``docs/*.md`` (the dated notes under ``docs/notes/`` record what was
  run on their date and are not examples);
- the commands: every line of a fenced code block (plain or ``bash``) that starts with
  ``hmodel ``, or an ``&& hmodel ...`` part of one, joined over trailing backslashes; a comment
  (`` # ...``) is not part of it;
- a **synopsis** is not an example and is left alone: a command with an ``[optional]`` part, an
  ``a|b`` alternative, ``...``/``…``, or a placeholder (a word in capitals only: ``FILE``,
  ``DIR``, ``SAMPLE``, ``A.safetensors``), and every command of a block that the line
  ``<!-- synopsis -->`` precedes. Every other command is an **example**.

What is checked of an example:

- every file it reads (a word, or a ``:``/``,``/``+``/``=``-separated part of one, that names a
  path: it has a ``/`` or a data file's suffix; ``--out`` excepted) exists in the repository,
  or is the ``--out`` of a command shown earlier on the same page (a database, a network);
- a cheap example runs, through the CLI's ``main``, in a temporary folder that mirrors the
  repository's top level (so ``examples/...`` and ``benchmarks/...`` resolve as from the
  repository root, and the outputs, ``results/...``, land in the temporary folder): exit 0 and
  its ``--out`` written. Examples with the same arguments on several pages run once;
- a slow example (``SLOW``: training, report-scale databases, YADE, finite elements, full
  calibrations, the whole study) is parsed against its command's options without running
  (an unknown option, a malformed value or an unwritable ``--out`` fails), and a calibration's
  ``--data`` tests are read.
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pytest
import typer.main

from hmodel.calibrate import parse_data_spec
from hmodel.cli.app import app, main

ROOT = Path(__file__).resolve().parents[1]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))

_FENCE = re.compile(r"^\s*```\s*([\w-]*)\s*$")
_SHELL = {"", "bash", "sh", "shell"}
_PLACEHOLDER = re.compile(r"[A-Z][A-Z_]*")
_DATA_SUFFIX = re.compile(r"\.(csv|toml|json|safetensors|npz|npy|parquet|zarr|h5)$")
_OUT = {"--out", "-o"}

#: The examples too slow to run in the test suite, each with why: a command matching one of
#: these patterns (searched in ``hmodel`` and its arguments joined by single spaces) is parsed,
#: not run. The examples that run take about 45 s of CPU together.
SLOW = (
    (r"^hmodel reproduce\b", "the whole study: a database, a network's accuracy, every path "
                             "twice (1.5 min with --quick)"),
    (r"^hmodel (data (generate|sample|info)|surrogate) ", "databases of 10^5-10^7 rows, "
                                                           "training, or the database or network "
                                                           "such a command writes"),
    (r"surrogate:\S+\.safetensors", "a network that a training command above writes"),
    (r"^hmodel dem |\bdem:", "YADE: DEM cells or a DEM sample (minutes)"),
    (r"^hmodel compare ", "every loading path, with each of two cell solvers (5-6 s of CPU)"),
    (r"^hmodel fem ", "a boundary-value problem, an H-model per Gauss point (20 s to minutes)"),
    (r"^hmodel calibrate (?!.*--starts [12]\b)", "a fit from the default 8 starts: hundreds of "
                                                 "model runs (20 s to 20 min); a fit from 1 or 2 "
                                                 "starts runs"),
    (r"--calibration ", "the calibrated model that a calibration shown above (parsed, not run) writes"),
)


@dataclass(frozen=True)
class Command:
    page: str
    line: int
    args: tuple[str, ...]  # after ``hmodel``
    marked_synopsis: bool = False

    @property
    def text(self) -> str:
        return " ".join(("hmodel", *self.args))

    def __str__(self) -> str:
        return f"{self.page}:{self.line}: {self.text}"


def words(text: str) -> tuple[str, ...]:
    """A shell line's words, its comment dropped: a ``#`` that starts a word outside quotes
    (``example:kfs#TMD12`` is one word, as in the shell)."""
    quote = None
    for i, ch in enumerate(text):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1].isspace()):
            text = text[:i]
            break
    return tuple(shlex.split(text))


def shown(page: Path) -> list[Command]:
    """The ``hmodel`` commands of a page's fenced shell blocks, in the page's order."""
    return shown_in(page.read_text(encoding="utf-8"), str(page.relative_to(ROOT)))


def shown_in(text: str, name: str) -> list[Command]:
    found: list[Command] = []
    lang = None  # the open fence's language; None outside a fence
    marked = False  # the open fence follows a ``<!-- synopsis -->`` line
    pending: tuple[int, list[str]] | None = None  # a command continued over backslashes
    previous = ""
    for no, line in enumerate(text.splitlines(), 1):
        fence = _FENCE.match(line)
        if fence:
            lang = fence.group(1) if lang is None else None
            marked = lang is not None and previous.strip() == "<!-- synopsis -->"
            pending = None
        previous = line
        if fence or lang not in _SHELL:
            continue
        text = line.strip()
        if pending is not None:
            pending[1].append(text)
            if text.endswith("\\"):
                continue
            start, parts = pending
            text, no, pending = " ".join(p.removesuffix("\\") for p in parts), start, None
            found.append(Command(name, no, words(text)[1:], marked))
            continue
        for part in text.split("&&"):
            part = part.strip()
            if not part.startswith("hmodel "):
                continue
            if part.endswith("\\"):
                pending = (no, [part])
            else:
                found.append(Command(name, no, words(part)[1:], marked))
    return found


def is_synopsis(command: Command) -> bool:
    if command.marked_synopsis:
        return True
    if any(c in w for w in command.args for c in "[]|…") or any("..." in w for w in command.args):
        return True
    return any(_PLACEHOLDER.fullmatch(p) for w in command.args for p in re.findall(r"\w+", w))


#: Every command the pages show, synopses included, and the examples among them.
COMMANDS = tuple(c for page in PAGES for c in shown(page))
EXAMPLES = tuple(c for c in COMMANDS if not is_synopsis(c))


def slow_reason(command: Command) -> str | None:
    return next((why for pattern, why in SLOW if re.search(pattern, command.text)), None)


def unique(commands: tuple[Command, ...]) -> list[Command]:
    """The first of the commands with the same arguments (the same example on several pages)."""
    seen: dict[tuple[str, ...], Command] = {}
    for c in commands:
        seen.setdefault(c.args, c)
    return list(seen.values())


def out_value(args: tuple[str, ...]) -> str | None:
    for i, word in enumerate(args[:-1]):
        if word in _OUT:
            return args[i + 1]
    return next((w.split("=", 1)[1] for w in args if w.startswith("--out=")), None)


def inputs(args: tuple[str, ...]) -> list[str]:
    """The paths a command line names as inputs: every word or part of one that names a
    file or folder, except the value of ``--out``."""
    paths = []
    skip = False
    for word in args:
        if skip or word in _OUT:
            skip = word in _OUT
            continue
        for part in re.split(r"[:,+=]", word):
            if "/" in part or _DATA_SUFFIX.search(part):
                paths.append(part)
    return paths


def written_before(command: Command) -> set[Path]:
    """The ``--out`` paths of the commands shown before ``command`` on its page."""
    outs = set()
    for c in COMMANDS:
        if c.page == command.page and c.line < command.line and out_value(c.args):
            outs.add(Path(out_value(c.args)))
    return outs


def parse(cli, args: tuple[str, ...]):
    """Parse a command line as ``hmodel`` would, down to its command's options (with their
    types, ranges and callbacks), without running the command; returns its context. ``cli``:
    hmodel's click command."""
    cmd = cli
    ctx = cmd.context_class(cmd, info_name="hmodel")
    args = list(args)
    while hasattr(cmd, "list_commands"):  # a group: the next word names its command
        name, args = args[0], args[1:]
        sub = cmd.get_command(ctx, name)
        assert sub is not None, f"no command {name!r} under {ctx.command_path!r}"
        cmd = sub
        if hasattr(cmd, "list_commands"):
            ctx = cmd.context_class(cmd, info_name=name, parent=ctx)
        else:
            return cmd.make_context(name, args, parent=ctx)
    raise AssertionError("not a command")


@pytest.fixture(scope="module")
def cli():
    return typer.main.get_command(app)


@pytest.fixture(scope="module")
def mirror(tmp_path_factory, monkeypatch_module):
    """A folder whose top-level entries link to the repository's, outputs excepted: commands
    run from it read the repository's files and write only into it."""
    where = tmp_path_factory.mktemp("docs-examples")
    for entry in ROOT.iterdir():
        if not entry.name.startswith(".") and entry.name not in {"results", "data", "out", "site", "build"}:
            (where / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    monkeypatch_module.chdir(where)
    return where


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as mp:
        yield mp


# The rule itself --------------------------------------------------------------------------

PAGE = """\
Text with `hmodel run iso` inline, not a command.

```bash
python3 -m venv .venv && hmodel reproduce --quick --out results
hmodel calibrate --data example:kfs#TMD12 \\
    --data example:kfs#TMD14 --out results/cal   # a comment's "quote
hmodel run biaxial --p0 200kPa [--undrained] --out results/b
hmodel run program FILE.toml --out results/p
```

```python
hmodel = 1
```

<!-- synopsis -->
```
hmodel surrogate refine start.safetensors --data start-sample --out al/
```
"""


def test_the_rule_reads_commands_and_tells_synopses():
    commands = shown_in(PAGE, "page.md")
    assert [(c.line, c.args) for c in commands] == [
        (4, ("reproduce", "--quick", "--out", "results")),
        (5, ("calibrate", "--data", "example:kfs#TMD12", "--data", "example:kfs#TMD14", "--out",
             "results/cal")),
        (7, ("run", "biaxial", "--p0", "200kPa", "[--undrained]", "--out", "results/b")),
        (8, ("run", "program", "FILE.toml", "--out", "results/p")),
        (17, ("surrogate", "refine", "start.safetensors", "--data", "start-sample", "--out", "al/")),
    ]
    assert [is_synopsis(c) for c in commands] == [False, False, True, True, True]
    assert inputs(commands[-1].args) == ["start.safetensors"]
    assert out_value(commands[1].args) == "results/cal"


def test_every_slow_pattern_matches_a_shown_example():
    # the list does not outlive the examples it was written for
    for pattern, _ in SLOW:
        assert any(re.search(pattern, c.text) for c in EXAMPLES), pattern
    assert any(slow_reason(c) is None for c in EXAMPLES)


def test_a_slow_command_with_a_wrong_option_does_not_parse(cli, mirror):
    # what the CLI turns into exit 2, a malformed command line
    with pytest.raises(Exception, match="--no-such-option") as unknown:
        parse(cli, ("fem", "footing", "--no-such-option", "1", "--out", "results/x"))
    with pytest.raises(Exception, match="valid number") as malformed:
        parse(cli, ("fem", "footing", "--mesh", "20x10", "--settlement", "abc", "--out", "results/x"))
    assert unknown.value.exit_code == malformed.value.exit_code == 2


# The examples -----------------------------------------------------------------------------

@pytest.mark.parametrize("command", EXAMPLES, ids=str)
def test_the_files_an_example_reads_exist(command):
    made = written_before(command)
    for path in map(Path, inputs(command.args)):
        assert (ROOT / path).exists() or any(path == p or p in path.parents for p in made), (
            f"{command}: {path} is neither shipped nor written by a command above it")


@pytest.mark.parametrize("command", [c for c in unique(EXAMPLES) if slow_reason(c)], ids=str)
def test_a_slow_example_parses(command, cli, mirror):
    ctx = parse(cli, command.args)
    if ctx.command.name == "calibrate":
        for spec in ctx.params["data"]:
            parse_data_spec(spec)


@pytest.mark.slow
@pytest.mark.parametrize("command", [c for c in unique(EXAMPLES) if not slow_reason(c)], ids=str)
def test_an_example_runs(command, mirror):
    out = out_value(command.args)
    if out is not None:
        assert mirror.resolve() in (mirror / out).resolve().parents, f"{command} writes outside the mirror"
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(list(command.args))
    assert code == 0, f"{command}: exit {code}: {err.getvalue().strip()[-2000:]}"
    if out is not None:
        assert (mirror / out).exists(), f"{command}: nothing written to {out}"
