"""The documentation site loads nothing from outside itself, and every page is reachable.

Read offline, a page whose math renderer, stylesheet or font comes from a CDN shows raw TeX and
fallback fonts. So the site serves its own math renderer (KaTeX, ``docs/javascripts/katex/``),
Material's Google Fonts are off (``theme.font: false``), and these tests check the
configuration, the stylesheets and the pages' own HTML without building anything; the built
site (``site/``, which the README's test command builds before the tests) is checked too when
it is at least as new as ``mkdocs.yml``.

The notes are left out of the navigation (``not_in_nav``); their index is the only way to them,
so it must list every one.
"""

from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
SITE = ROOT / "site"

#: A URL that leaves the site: a scheme (https:, http:, ftp:, ...) or a protocol-relative
#: ``//host``. ``data:`` URLs are inline and stay.
_EXTERNAL = re.compile(r"^\s*(?:[a-z][a-z0-9+.-]*:|//)", re.IGNORECASE)
_CSS_URL = re.compile(r"url\(\s*['\"]?([^'\")]+)['\"]?\s*\)", re.IGNORECASE)
_CSS_IMPORT = re.compile(r"@import\s+['\"]([^'\"]+)['\"]", re.IGNORECASE)  # @import url(...) is a url()


def external(url: str) -> bool:
    return bool(_EXTERNAL.match(url)) and not url.strip().lower().startswith("data:")


def config() -> dict:
    yaml = pytest.importorskip("yaml")

    class Loader(yaml.SafeLoader):  # mkdocs.yml may hold !ENV or !!python/name tags
        pass
    Loader.add_multi_constructor("", lambda loader, suffix, node: None)
    return yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=Loader)


def css_urls(text: str) -> list[str]:
    """Every ``url(...)`` and ``@import`` target of a stylesheet."""
    return _CSS_URL.findall(text) + _CSS_IMPORT.findall(text)


class Resources(HTMLParser):
    """The URLs an HTML page loads by itself: scripts, stylesheets and other ``<link>``
    resources, images, frames, media, and ``url()`` in inline styles. Links a reader follows
    (``<a href>``, ``<link rel=canonical|alternate>``) are not loads."""

    FOLLOWED = {"canonical", "alternate", "next", "prev", "author", "license", "help", "search"}

    def __init__(self):
        super().__init__()
        self.urls: list[str] = []
        self._style = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "link":
            rel = set((a.get("rel") or "").lower().split())
            if a.get("href") and not rel <= self.FOLLOWED:
                self.urls.append(a["href"])
        elif tag in ("script", "img", "iframe", "audio", "video", "source", "embed", "track"):
            self.urls += [a[k] for k in ("src", "srcset") if a.get(k)]
        elif tag == "object" and a.get("data"):
            self.urls.append(a["data"])
        if a.get("style"):
            self.urls += css_urls(a["style"])
        self._style = tag == "style"

    def handle_data(self, data):
        if self._style:
            self.urls += css_urls(data)

    def handle_endtag(self, tag):
        self._style = False


def loads(html: str) -> list[str]:
    p = Resources()
    p.feed(html)
    return p.urls


# --------------------------------------------------------------------------- the checks' own checks

def test_the_checks_see_what_a_cdn_page_loads():
    page = ('<link rel="stylesheet" href="https://fonts.googleapis.com/css?family=Roboto">'
            '<link rel="preconnect" href="https://fonts.gstatic.com">'
            '<link rel="canonical" href="https://example.org/page/">'
            '<script src="https://unpkg.com/mathjax@3/es5/tex-mml-chtml.js"></script>'
            '<script src="../javascripts/katex/katex.min.js"></script>'
            '<a href="https://yade-dem.org">YADE</a>'
            '<style>@font-face{src:url(//cdn.example/f.woff2)}</style>'
            '<div style="background:url(data:image/svg+xml;utf8,x)"></div>')
    found = [u for u in loads(page) if external(u)]
    assert found == ["https://fonts.googleapis.com/css?family=Roboto", "https://fonts.gstatic.com",
                     "https://unpkg.com/mathjax@3/es5/tex-mml-chtml.js", "//cdn.example/f.woff2"]
    assert css_urls('@import url("https://x.org/a.css"); @import "b.css"; a{b:url(fonts/c.woff2)}') \
        == ["https://x.org/a.css", "fonts/c.woff2", "b.css"]


# --------------------------------------------------------------------------- configuration and sources

def test_config_loads_no_script_stylesheet_or_font_from_outside():
    cfg = config()
    theme = cfg.get("theme") or {}
    assert theme.get("font") is False, \
        "mkdocs.yml: theme.font must be false (Material loads Google Fonts otherwise)"
    assert not cfg.get("repo_url"), \
        "mkdocs.yml: repo_url makes Material fetch the repository's statistics from outside"
    for key in ("extra_javascript", "extra_css"):
        for entry in cfg.get(key) or []:
            url = entry if isinstance(entry, str) else (entry or {}).get("path", "")
            assert not external(url), f"mkdocs.yml {key}: {url} is loaded from outside the site"
            assert (DOCS / url).is_file(), f"mkdocs.yml {key}: docs/{url} does not exist"


def test_math_is_rendered_by_the_bundled_katex():
    cfg = config()
    exts = {}
    for e in cfg.get("markdown_extensions") or []:
        exts.update(e if isinstance(e, dict) else {e: None})
    assert (exts.get("pymdownx.arithmatex") or {}).get("generic") is True, \
        "the render script (docs/javascripts/katex-render.js) reads arithmatex's generic output"
    scripts = cfg.get("extra_javascript") or []
    assert scripts.index("javascripts/katex/katex.min.js") < scripts.index("javascripts/katex-render.js")
    assert "javascripts/katex/katex.min.css" in (cfg.get("extra_css") or [])
    assert (DOCS / "javascripts/katex/LICENSE").is_file()


def test_bundled_stylesheets_name_only_their_own_files():
    sheets = sorted(DOCS.rglob("*.css"))
    assert sheets
    for css in sheets:
        for url in css_urls(css.read_text(encoding="utf-8")):
            if url.strip().lower().startswith("data:"):
                continue
            assert not external(url), f"{css.relative_to(ROOT)} loads {url} from outside the site"
            assert (css.parent / url.split("?")[0].split("#")[0]).is_file(), \
                f"{css.relative_to(ROOT)} names {url}, which is not there"


def test_pages_load_nothing_from_outside():
    for page in sorted(DOCS.rglob("*.md")) + sorted(DOCS.rglob("*.html")):
        text = page.read_text(encoding="utf-8")
        # fenced code shows HTML, it does not load it
        text = re.sub(r"^(```|~~~).*?^\1", "", text, flags=re.MULTILINE | re.DOTALL)
        bad = [u for u in loads(text) if external(u)]
        assert not bad, f"{page.relative_to(ROOT)} loads {bad} from outside the site"


# --------------------------------------------------------------------------- the built site

def _fresh_site() -> Path:
    index = SITE / "index.html"
    if not index.is_file():
        pytest.skip("no built site: mkdocs build --strict (the README's test command builds it)")
    if index.stat().st_mtime < (ROOT / "mkdocs.yml").stat().st_mtime:
        pytest.skip("site/ is older than mkdocs.yml: rebuild it (mkdocs build --strict)")
    return SITE


def test_built_site_loads_nothing_from_outside():
    site = _fresh_site()
    pages = sorted(site.rglob("*.html"))
    assert pages
    for page in pages:
        bad = [u for u in loads(page.read_text(encoding="utf-8")) if external(u)]
        assert not bad, f"{page.relative_to(site)} loads {bad} from outside the site"
    for css in sorted(site.rglob("*.css")):
        bad = [u for u in css_urls(css.read_text(encoding="utf-8")) if external(u)]
        assert not bad, f"{css.relative_to(site)} loads {bad} from outside the site"


def test_built_pages_carry_math_for_katex():
    site = _fresh_site()
    html = (site / "model3d" / "index.html").read_text(encoding="utf-8")
    assert html.count('class="arithmatex"') >= 10
    assert "katex.min.js" in html and "katex-render.js" in html and "mathjax" not in html.lower()


# --------------------------------------------------------------------------- the notes

def test_every_note_is_listed_in_the_notes_index_and_none_in_the_navigation():
    notes = sorted(p.name for p in (DOCS / "notes").glob("2*.md"))
    assert notes
    index = (DOCS / "notes" / "index.md").read_text(encoding="utf-8")
    linked = set(re.findall(r"\]\(([^)#\s]+\.md)", index))
    assert [n for n in notes if n not in linked] == []
    assert [n for n in linked if not (DOCS / "notes" / n).is_file()] == []
    cfg = config()
    assert "notes/2" not in repr(cfg.get("nav")), "the notes belong under their index, not in nav"
    assert "/notes/2*.md" in (cfg.get("not_in_nav") or "")
