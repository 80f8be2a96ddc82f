"""MkDocs hook: the command-line reference, generated at build time from the ``hmodel`` CLI itself.

``<!-- cli-reference -->`` in ``docs/cli.md`` is replaced by one section per command (usage,
help text, arguments and options with their defaults), read from the Typer application in
:mod:`hmodel.cli.app` through Click's introspection, so the page cannot drift from the code.
"""

from __future__ import annotations

import enum
import logging
import sys
from pathlib import Path

log = logging.getLogger("mkdocs.hooks.cli_reference")

PAGE = "cli.md"
MARKER = "<!-- cli-reference -->"


def _cell(s) -> str:
    return " ".join(str(s).split()).replace("|", "\\|")


def _default(p) -> str:
    if getattr(p, "is_flag", False) and not getattr(p, "secondary_opts", None):
        return ""
    d = p.default
    if d is None or callable(d) or d in ((), []) or d is Ellipsis:
        return ""
    if isinstance(d, (list, tuple)):
        d = ", ".join(map(str, d))
    return f"`{getattr(d, 'value', d)}`"


def _annotation(p):
    desc = getattr(p, "type_descriptor", None)  # Typer >= 0.25 (vendored Click)
    return getattr(desc, "annotation", None)


def _kind(p) -> str:
    if getattr(p, "is_flag", False):
        return "flag"
    t = getattr(p, "type", None)  # Click's own parameter types (older Typer)
    if t is not None:
        choices = getattr(t, "choices", None)
        if choices:
            return " | ".join(f"`{c}`" for c in choices)
        return getattr(t, "name", "") or ""
    ann = _annotation(p)
    for arg in getattr(ann, "__args__", ()) or ():  # list[X], Optional[X]
        if arg is not type(None):
            ann = arg
            break
    if isinstance(ann, type) and issubclass(ann, enum.Enum):
        return " | ".join(f"`{m.value}`" for m in ann)
    names = {str: "text", int: "integer", float: "number", bool: "flag", Path: "path"}
    return names.get(ann, getattr(ann, "__name__", "") if ann is not None else "")


def _is_argument(p) -> bool:
    return "Argument" in type(p).__name__


def _command(cmd, path: list[str]) -> list[str]:
    import typer

    ctx = typer.Context(cmd, info_name=" ".join(path))
    lines = [f"### `{' '.join(path)}`", ""]
    usage = " ".join(path + cmd.collect_usage_pieces(ctx))
    lines += ["```", usage, "```", ""]
    help_text = (cmd.help or "").strip()
    if help_text:
        # Typer keeps the docstring; a "\\b" line (Click's no-rewrap marker) is not text.
        lines += help_text.replace("\b", "").splitlines() + [""]
    rows = []
    for p in cmd.params:
        if getattr(p, "hidden", False) or p.name == "help":
            continue
        if _is_argument(p):
            name = f"`{(p.metavar or p.name).upper()}`" + (" (required)" if p.required else "")
        else:
            name = ", ".join(f"`{o}`" for o in list(p.opts) + list(p.secondary_opts))
            name += (" (repeatable)" if p.multiple else "") + (" (required)" if p.required else "")
        rows.append((name, _kind(p), _default(p), getattr(p, "help", "") or ""))
    if rows:
        lines += ["| argument or option | type | default | meaning |", "|---|---|---|---|"]
        lines += [f"| {_cell(a)} | {_cell(b)} | {_cell(c)} | {_cell(d)} |" for a, b, c, d in rows]
        lines.append("")
    commands = getattr(cmd, "commands", None)
    if commands:
        for name in cmd.list_commands(ctx):
            sub = cmd.get_command(ctx, name)
            if sub is not None and not getattr(sub, "hidden", False):
                lines += _command(sub, path + [name])
    return lines


def reference() -> str:
    """The reference of every ``hmodel`` command, as Markdown."""
    import typer

    from hmodel.cli.app import app

    root = typer.main.get_command(app)
    ctx = typer.Context(root, info_name="hmodel")
    out: list[str] = []
    for name in root.list_commands(ctx):
        out += _command(root.get_command(ctx, name), ["hmodel", name])
    return "\n".join(out) + "\n"


def on_page_markdown(markdown, page, config, files, **kwargs):
    if page.file.src_uri != PAGE or MARKER not in markdown:
        return markdown
    src = Path(config["config_file_path"]).resolve().parent / "src"
    if str(src) not in sys.path:
        sys.path.insert(0, str(src))
    try:
        text = reference()
    except Exception as e:  # noqa: BLE001 - any failure to import the CLI is a docs failure
        log.warning("cli reference: cannot read the hmodel command line: %s: %s", type(e).__name__, e)
        text = "*The command-line reference could not be generated.*\n"
    return markdown.replace(MARKER, text)
