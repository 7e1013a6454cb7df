"""The HTML triage report in a real headless browser: thumbnails load, clicks sort, typing filters.

Chromium is driven through the Chrome DevTools Protocol over a pipe
(``--remote-debugging-pipe``: JSON messages ending in a NUL byte on file
descriptors 3 and 4), so the test needs Debian's ``chromium`` package and no
Python package beyond the standard library. Without Chromium the test fails
and says how to install it; ``ROCKSCAN_NO_BROWSER=1`` leaves it out.
"""

from __future__ import annotations

import base64
import io
import json
import os
import select
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_spec_path, read_spec
from rockscan.io.report import read_provenance, read_rows
from rockscan.run.triage import TriageConfig, triage_folder

pytestmark = pytest.mark.skipif(
    os.environ.get("ROCKSCAN_NO_BROWSER") == "1",
    reason="ROCKSCAN_NO_BROWSER=1: the headless-browser check of the HTML report is switched off",
)

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--remote-debugging-pipe",
    "--window-size=1200,900",
)


def _chromium_binary() -> str:
    for name in (os.environ.get("ROCKSCAN_CHROMIUM"), "chromium", "chromium-browser", "google-chrome"):
        if name and shutil.which(name):
            return shutil.which(name)
    pytest.fail(
        "Chromium is needed to check the HTML report: install Debian's 'chromium' package "
        "(apt-get install chromium), point ROCKSCAN_CHROMIUM at a Chrome binary, "
        "or set ROCKSCAN_NO_BROWSER=1 to leave this check out"
    )


class Browser:
    """A headless Chromium page driven over the DevTools pipe."""

    def __init__(self, binary: str, profile: Path) -> None:
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()

        def plumb() -> None:
            # Chromium reads commands on fd 3 and writes answers on fd 4.
            os.dup2(to_chrome_r, 3)
            os.dup2(from_chrome_w, 4)

        self._proc = subprocess.Popen(
            [binary, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "about:blank"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            # 3 and 4 are made by plumb(); they must survive the closing of other descriptors.
            pass_fds=(3, 4),
            preexec_fn=plumb,
        )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._buffer = b""
        self._next_id = 0
        self._events: list[dict] = []
        try:
            target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
            attached = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})
            self._session = attached["sessionId"]
            self.send("Page.enable", session=True)
        except BaseException:
            self.close()
            raise

    def _read_message(self, deadline: float) -> dict:
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([self._from_chrome], [], [], max(left, 0))
            if not ready:
                raise TimeoutError("Chromium did not answer in time")
            chunk = os.read(self._from_chrome, 1 << 16)
            if not chunk:
                raise ConnectionError("Chromium closed the DevTools pipe")
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(message)

    def send(self, method: str, params: dict | None = None, *, session: bool = False, timeout: float = 30.0):
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = self._session
        os.write(self._to_chrome, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            answer = self._read_message(deadline)
            if answer.get("id") == self._next_id:
                if "error" in answer:
                    raise RuntimeError(f"{method}: {answer['error']}")
                return answer["result"]
            self._events.append(answer)

    def wait_event(self, method: str, timeout: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            for i, event in enumerate(self._events):
                if event.get("method") == method:
                    return self._events.pop(i)
            self._events.append(self._read_message(deadline))

    def open(self, url: str) -> None:
        self._events.clear()
        self.send("Page.navigate", {"url": url}, session=True)
        self.wait_event("Page.loadEventFired")

    def js(self, expression: str):
        result = self.send(
            "Runtime.evaluate",
            {"expression": expression, "returnByValue": True, "awaitPromise": True},
            session=True,
        )
        if "exceptionDetails" in result:
            raise RuntimeError(f"page script failed: {result['exceptionDetails']}")
        return result["result"].get("value")

    def click(self, selector: str) -> None:
        """Press and release the mouse on an element, as a person does."""
        x, y = self.js(
            f"(() => {{ const r = document.querySelector({json.dumps(selector)}).getBoundingClientRect();"
            " return [r.x + r.width / 2, r.y + r.height / 2]; })()"
        )
        for kind in ("mousePressed", "mouseReleased"):
            self.send(
                "Input.dispatchMouseEvent",
                {"type": kind, "x": x, "y": y, "button": "left", "clickCount": 1},
                session=True,
            )

    def type_text(self, text: str) -> None:
        self.send("Input.insertText", {"text": text}, session=True)

    def screenshot(self) -> bytes:
        return base64.b64decode(self.send("Page.captureScreenshot", {"format": "png"}, session=True)["data"])

    def close(self) -> None:
        try:
            self.send("Browser.close", timeout=10)
        except (TimeoutError, ConnectionError, RuntimeError, OSError):
            pass
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        os.close(self._to_chrome)
        os.close(self._from_chrome)


@pytest.fixture(scope="module")
def sheet(tmp_path_factory, default_lib):
    """An HTML report of 8 rendered photos (4 shapes) and 2 broken files."""
    root = tmp_path_factory.mktemp("sheet")
    specs = {s.name: s.params for s in read_spec(default_spec_path())}
    rng = np.random.default_rng(7)
    config = RenderConfig(rows=160, cols=200)
    for i in range(8):
        name = ("five-armed-star", "egg", "six-pointed-star", "rounded-triangle")[i % 4]
        suffix = (".png", ".jpg")[i % 2]
        path = root / "photos" / ("", "sub")[i % 2] / f"{i:02d}-{name}{suffix}"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(render_photo(specs[name], config, rng=rng, name=name).encode(suffix))
    (root / "photos" / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    (root / "photos" / "sub" / "empty.jpg").write_bytes(b"")
    report = root / "report.html"
    summary = triage_folder(root / "photos", report, default_lib, TriageConfig(workers=1))
    assert (summary.n_rows, summary.n_errors) == (10, 2)
    return report, list(read_rows(report))


@pytest.fixture(scope="module")
def page(sheet, tmp_path_factory):
    browser = Browser(_chromium_binary(), tmp_path_factory.mktemp("chromium-profile"))
    try:
        browser.open(sheet[0].as_uri())
        yield browser
    finally:
        browser.close()


def _shown(page: Browser, key: str) -> list[str]:
    return page.js(
        f"Array.from(document.querySelectorAll('figure.card')).filter(c => !c.hidden).map(c => c.dataset.{key})"
    )


def test_every_thumbnail_loads(page, sheet):
    _, rows = sheet
    images = page.js(
        "Array.from(document.images).map(i => [i.alt, i.complete, i.naturalWidth, i.naturalHeight])"
    )
    ok = sorted(r["path"] for r in rows if r["error"] is None)
    assert sorted(alt for alt, *_ in images) == ok
    assert all(complete and (width, height) == (144, 115) for _, complete, width, height in images)
    assert page.js("document.querySelectorAll('.noimage').length") == 2


def test_the_page_opens_ranked_and_draws_something(page, sheet):
    _, rows = sheet
    assert _shown(page, "path") == [r["path"] for r in rows]
    assert page.js("document.getElementById('count').textContent") == "10 of 10 shown"
    shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("L"))
    assert shot.shape[1] == 1200 and shot.std() > 20


def _as_numbers(values: list[str]) -> list[float | None]:
    return [float(v) if v else None for v in values]


def test_clicking_a_header_sorts_and_clicking_again_reverses(page, sheet):
    _, rows = sheet
    page.click("button[data-key=mscore]")
    values = _as_numbers(_shown(page, "mscore"))
    ranked = [v for v in values if v is not None]
    assert ranked == sorted(ranked, reverse=True) and values[-2:] == [None, None]
    assert page.js("document.querySelector('button[data-key=mscore]').getAttribute('aria-pressed')") == "true"
    page.click("button[data-key=mscore]")
    values = _as_numbers(_shown(page, "mscore"))
    ranked = [v for v in values if v is not None]
    # Errors stay last whichever way the sort goes.
    assert ranked == sorted(ranked) and values[-2:] == [None, None]
    page.click("button[data-key=path]")
    assert _shown(page, "path") == sorted(r["path"].lower() for r in rows)
    page.click("button[data-key=rank]")
    assert _shown(page, "path") == [r["path"] for r in rows]


def test_typing_and_ticking_filter_the_sheet(page, sheet):
    _, rows = sheet
    page.click("#filter")
    page.type_text("star")
    stars = [r["path"] for r in rows if "star" in r["path"] or "star" in (r["match"] or r["nearest"] or "")]
    assert len(stars) == 4 and _shown(page, "path") == stars
    assert page.js("document.getElementById('count').textContent") == "4 of 10 shown"
    page.js(
        "document.getElementById('filter').value = ''; document.getElementById('filter').dispatchEvent(new Event('input'))"
    )
    page.click("#show-errors")
    assert _shown(page, "path") == [r["path"] for r in rows if r["error"] is None]
    page.click("#show-errors")
    assert len(_shown(page, "path")) == 10


def test_each_card_opens_its_photo(page, sheet):
    _, rows = sheet
    links = page.js(
        "Array.from(document.querySelectorAll('figure.card')).map(c => "
        "[c.dataset.path, c.querySelector('a.photo').getAttribute('href'), "
        "decodeURIComponent(new URL(c.querySelector('a.photo').href).pathname)])"
    )
    assert len(links) == len(rows)
    for path, href, target in links:
        assert not href.startswith("/")  # relative: the report and its photos move together
        assert Path(target) == Path(path).resolve()


def test_the_interest_filter_and_the_footer(page, sheet):
    report, rows = sheet
    page.js(
        "(() => { const f = document.getElementById('min-interest'); f.value = '1'; f.dispatchEvent(new Event('input')); })()"
    )
    assert _shown(page, "path") == [r["path"] for r in rows if r["error"] is None and r["interest"] >= 1]
    page.js(
        "(() => { const f = document.getElementById('min-interest'); f.value = ''; f.dispatchEvent(new Event('input')); })()"
    )
    assert len(_shown(page, "path")) == 10
    footer = page.js("document.querySelector('footer').innerText")
    provenance = json.loads(page.js("document.getElementById('provenance-json').textContent"))
    assert provenance == read_provenance(report)
    assert provenance["library"]["sha256"] in footer and "rockscan" in footer
