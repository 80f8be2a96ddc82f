"""MkDocs hook: ``mkdocs build --strict -q`` still fails on warnings.

``-q`` raises the ``mkdocs`` logger to ERROR, so warnings are dropped before the strict-mode
counter sees them, and a strict quiet build passes with broken links. With ``strict: true``
this hook lowers the logger back to WARNING: a quiet build prints nothing unless a warning
makes it fail, and then it says why.
"""

from __future__ import annotations

import logging


def on_config(config, **kwargs):
    log = logging.getLogger("mkdocs")
    if config.get("strict") and log.getEffectiveLevel() > logging.WARNING:
        log.setLevel(logging.WARNING)
    return config
