"""Real-browser checks of the lab's HTML reports with headless Chromium (test helper, not part of renderlab).

* :func:`find_chromium` locates the browser (``$CHROMIUM``, then ``chromium``, ``chromium-browser``,
  ``google-chrome``); ``None`` when there is none.
* :func:`dump_dom` returns the DOM after the page's load event (``--dump-dom``).
* :func:`screenshot` writes a PNG of the page at a given window size (``--screenshot``).
* :func:`check_report` lists what is wrong with a report page: every ``<img>`` must be a file inside
  the report folder that decodes (PNG/JPEG/GIF by Pillow, SVG as XML with an ``<svg>`` root), local
  links (``<a href>``, ``<link href>``, ``<script src>``, ...) must exist, in-page ``#fragments`` must
  name an element, and, in the real browser, every image must have a non-zero ``naturalWidth`` after
  ``window.onload`` and no resource or script error may fire.

Each Chromium run gets a fresh temporary profile and its own process group, killed on timeout.
Reusable for any report: ``assert check_report(folder / "index.html") == []``.
"""

from __future__ import annotations

import html
import os
import re
import shutil
import signal
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

TIMEOUT_S = 60
_CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
_FLAGS = ("--headless", "--disable-gpu", "--no-sandbox", "--no-first-run", "--disable-extensions",
          "--disable-dev-shm-usage", "--hide-scrollbars", "--mute-audio")
_LINK_ATTRS = {("a", "href"), ("link", "href"), ("script", "src"), ("iframe", "src"), ("source", "src"),
               ("video", "src"), ("audio", "src"), ("object", "data"), ("embed", "src")}
_REMOTE = ("http", "https", "ftp", "mailto", "tel", "data", "javascript")
_PROBE = """<script>(function () {
  var errs = [];
  function note(msg) { errs.push(msg); document.documentElement.setAttribute("data-rl-errors", errs.join(" | ")); }
  window.addEventListener("error", function (e) {
    var t = e.target;
    if (t && t !== window && (t.src || t.href)) { note("cannot load " + (t.getAttribute("src") || t.getAttribute("href"))); }
    else { note("script error: " + e.message); }
  }, true);
  window.addEventListener("load", function () {
    document.querySelectorAll("img").forEach(function (im) {
      im.setAttribute("data-rl-width", String(im.naturalWidth));
    });
    document.documentElement.setAttribute("data-rl-loaded", "1");
  });
})();</script>"""


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome executable (``$CHROMIUM`` first), or None."""
    env = os.environ.get("CHROMIUM")
    if env and shutil.which(env):
        return shutil.which(env)
    for name in _CANDIDATES:
        if shutil.which(name):
            return shutil.which(name)
    return None


def _chromium(args: list[str], timeout: float) -> str:
    """Run headless Chromium with ``args`` in a fresh profile; its stdout (RuntimeError on failure)."""
    exe = find_chromium()
    if exe is None:
        raise RuntimeError("no Chromium found (install Debian's 'chromium' package or set $CHROMIUM)")
    with tempfile.TemporaryDirectory(prefix="rl-chromium-") as profile:
        cmd = [exe, *_FLAGS, f"--user-data-dir={profile}", *args]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                start_new_session=True, env={**os.environ, "HOME": profile})
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)  # the browser's own process group only
            proc.communicate()
            raise RuntimeError(f"chromium timed out after {timeout:g} s: {' '.join(args)}") from None
    if proc.returncode != 0:
        raise RuntimeError(f"chromium exited with {proc.returncode}: {err.strip()[-2000:]}")
    return out


def dump_dom(html_path, *, timeout: float = TIMEOUT_S) -> str:
    """The page's DOM (serialized HTML) after its load event, as headless Chromium sees it."""
    return _chromium(["--dump-dom", Path(html_path).resolve().as_uri()], timeout)


def screenshot(html_path, png_path, width: int = 1280, height: int = 2400, *,
               timeout: float = TIMEOUT_S) -> Path:
    """Write a PNG screenshot of the page (window ``width`` x ``height`` px); returns its path."""
    png = Path(png_path).resolve()
    png.parent.mkdir(parents=True, exist_ok=True)
    png.unlink(missing_ok=True)
    _chromium([f"--screenshot={png}", f"--window-size={int(width)},{int(height)}",
               Path(html_path).resolve().as_uri()], timeout)
    if not png.is_file() or png.stat().st_size == 0:
        raise RuntimeError(f"chromium wrote no screenshot {png}")
    return png


# ---------------------------------------------------------------------------------- static part
class _Refs(HTMLParser):
    """Collects (tag, attribute, value) references, element ids and the attributes of <html>/<img>."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.refs: list[tuple[str, str, str]] = []
        self.ids: set[str] = set()
        self.html_attrs: dict[str, str] = {}
        self.imgs: list[dict[str, str]] = []

    def handle_starttag(self, tag, attrs):
        a = {k: (v or "") for k, v in attrs}
        for key in ("id", "name"):
            if a.get(key):
                self.ids.add(a[key])
        if tag == "html":
            self.html_attrs = a
        if tag == "img":
            self.imgs.append(a)
            if "src" in a:
                self.refs.append(("img", "src", a["src"]))
        for t, attr in _LINK_ATTRS:
            if tag == t and attr in a:
                self.refs.append((tag, attr, a[attr]))


def _parse(text: str) -> _Refs:
    p = _Refs()
    p.feed(text)
    p.close()
    return p


def decode_problem(path: Path) -> str | None:
    """Why ``path`` is not a readable image (None if it is): SVG must parse as XML with an <svg> root,
    anything else must be fully decoded by Pillow (PNG signature checked first)."""
    data = path.read_bytes()
    if path.suffix.lower() == ".svg":
        try:
            root = ET.fromstring(data)
        except ET.ParseError as exc:
            return f"SVG does not parse ({exc})"
        return None if root.tag.rsplit("}", 1)[-1] == "svg" else f"SVG root is <{root.tag}>"
    if path.suffix.lower() == ".png" and data[:8] != b"\x89PNG\r\n\x1a\n":
        return "not a PNG (bad signature)"
    from PIL import Image

    try:
        with Image.open(path) as im:
            im.load()
            if im.width < 1 or im.height < 1:
                return "empty image"
    except Exception as exc:  # noqa: BLE001 - any decoder failure is the finding
        return f"does not decode ({type(exc).__name__}: {exc})"
    return None


def _static_problems(page: Path, refs: _Refs) -> list[str]:
    folder = page.parent.resolve()
    problems = []
    for tag, attr, value in refs.refs:
        where = f"<{tag} {attr}={value!r}>"
        url = urlsplit(value.strip())
        if url.scheme in _REMOTE or url.netloc:
            if tag == "img" and url.scheme != "data":
                problems.append(f"{where}: remote image (a report must be self-contained)")
            continue
        if not url.path:  # "#fragment" (or empty)
            if url.fragment and url.fragment not in refs.ids:
                problems.append(f"{where}: no element with id {url.fragment!r}")
            elif not url.fragment and tag == "img":
                problems.append(f"{where}: empty src")
            continue
        target = (folder / unquote(url.path)).resolve() if url.scheme != "file" else Path(unquote(url.path))
        if not target.is_relative_to(folder):
            problems.append(f"{where}: points outside the report folder")
        elif not target.is_file():
            problems.append(f"{where}: missing file {target.relative_to(folder)}")
        elif tag == "img" or target.suffix.lower() in (".png", ".svg", ".jpg", ".jpeg", ".gif"):
            why = decode_problem(target)
            if why:
                problems.append(f"{where}: {why}")
    return problems


# --------------------------------------------------------------------------------- browser part
def _probe_copy(page: Path, text: str, tmp: Path) -> Path:
    """A copy of the page in ``tmp`` that resolves URLs against the report folder and runs the probe."""
    inject = f'<base href="{html.escape(page.parent.resolve().as_uri())}/">' + _PROBE
    m = re.search(r"<head\b[^>]*>", text, flags=re.IGNORECASE)
    text = text[:m.end()] + inject + text[m.end():] if m else inject + text
    out = tmp / "probe.html"
    out.write_text(text, encoding="utf-8")
    return out


def _browser_problems(page: Path, text: str, timeout: float) -> list[str]:
    with tempfile.TemporaryDirectory(prefix="rl-report-probe-") as tmp:
        dom = _parse(dump_dom(_probe_copy(page, text, Path(tmp)), timeout=timeout))
    if dom.html_attrs.get("data-rl-loaded") != "1":
        return ["browser: the page did not finish loading (no load event before the DOM dump)"]
    problems = [f"browser: {e}" for e in dom.html_attrs.get("data-rl-errors", "").split(" | ") if e]
    for im in dom.imgs:
        if im.get("data-rl-width", "0") in ("", "0"):
            problems.append(f"browser: <img src={im.get('src', '')!r}> has naturalWidth 0 (not displayed)")
    return problems


def check_report(html_path, *, browser: bool = True, timeout: float = TIMEOUT_S) -> list[str]:
    """Problems of an HTML report (an empty list when it is fine).

    Parameters
    ----------
    html_path : str or os.PathLike
        The page (its folder is the report folder: every local reference must stay inside it).
    browser : bool, optional
        Also open the page in headless Chromium and check that each image was displayed
        (``naturalWidth`` > 0 after ``window.onload``) and that no resource/script error fired.
    timeout : float, optional
        Seconds for the browser run.

    Returns
    -------
    list of str
        One line per problem, naming the element.
    """
    page = Path(html_path)
    if not page.is_file():
        return [f"report page {page} does not exist"]
    text = page.read_text(encoding="utf-8")
    refs = _parse(text)
    problems = _static_problems(page, refs)
    if not refs.imgs:
        problems.append("the page has no <img> at all")
    if browser:
        problems += _browser_problems(page, text, timeout)
    return problems
