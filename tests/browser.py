"""A headless Chromium for tests that open pages the way a reader does (``file://``).

Chromium's headless shell (Debian package ``chromium-headless-shell``; `.ci/run` installs
it when it can) loads a page from its folder and reports, for every ``<img>``, whether it
decoded and, for every link, whether its target loads.  `browser` is None without one:
the tests that need it skip.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

BROWSERS = ("chromium-headless-shell", "chromium", "chromium-browser", "google-chrome",
            "headless_shell")

#: Appended to a copy of the page: lists each image (decoded?) and link (loads?) as JSON.
CHECK_SCRIPT = """<script>
window.addEventListener('load', function () {
  var out = {images: [], links: []};
  document.querySelectorAll('img').forEach(function (i) {
    out.images.push([i.getAttribute('src'), i.complete && i.naturalWidth > 0]);
  });
  document.querySelectorAll('a[href]').forEach(function (a) {
    var h = a.getAttribute('href');
    if (h.charAt(0) === '#') {
      out.links.push([h, h === '#' || !!document.getElementById(h.slice(1))]);
      return;
    }
    var ok = false;
    try { var x = new XMLHttpRequest(); x.open('GET', a.href, false); x.send();
          ok = x.status === 0 || x.status === 200; } catch (e) { ok = false; }
    out.links.push([h, ok]);
  });
  var p = document.createElement('pre'); p.id = 'fluxcal-check';
  p.textContent = JSON.stringify(out); document.body.appendChild(p);
});
</script>"""


def browser() -> str | None:
    """Path of a headless Chromium, or None."""
    return next((p for b in BROWSERS if (p := shutil.which(b))), None)


def browser_check(page: Path) -> dict[str, list[list]]:
    """Open ``page`` in headless Chromium from its folder; return the images and links."""
    probe = page.with_name(".fluxcal-check.html")
    probe.write_text(page.read_text().replace("</body>", CHECK_SCRIPT + "</body>"))
    try:
        done = subprocess.run(
            [browser(), "--no-sandbox", "--disable-gpu", "--allow-file-access-from-files",
             "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
            capture_output=True, text=True, timeout=60)
    finally:
        probe.unlink()
    dom = done.stdout
    # the page's own scripts may add attributes to the element (a theme's tabindex)
    found = re.search(r'<pre id="fluxcal-check"[^>]*>(.*?)</pre>', dom, re.S)
    if found is None:
        raise AssertionError(f"the page's check did not run: {done.stderr[-500:]}")
    return json.loads(found.group(1).replace("&amp;", "&"))
