// Renders the math that pymdownx.arithmatex (generic mode) leaves in the page: every
// element of class "arithmatex" holds one formula, \( ... \) inline or \[ ... \] displayed.
// KaTeX is served from this site (javascripts/katex/), so the pages need no network.
// document$ is Material's page observable: it fires on the first load and after each
// instant-navigation page change.
document$.subscribe(({ body }) => {
  for (const el of body.querySelectorAll(".arithmatex")) {
    const tex = el.textContent.trim();
    const display = tex.startsWith("\\[");
    if (!display && !tex.startsWith("\\(")) continue;  // already rendered
    katex.render(tex.slice(2, -2), el, { displayMode: display, throwOnError: false });
  }
});
