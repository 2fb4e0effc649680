"""Debian's chromium, headless, driven by Playwright (never a browser download of Playwright's own), for the viewer's
tests and benchmarks/viewer.py. Without chromium this raises: the viewer's tests fail, they do not skip."""

import contextlib
import shutil

from playwright.sync_api import sync_playwright

# WebGL 2 on the CPU (SwiftShader through ANGLE): headless Chromium has no GPU here.
CHROMIUM_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]


def chromium_path() -> str:
    path = shutil.which("chromium")
    if path is None:
        raise RuntimeError("Debian's chromium is not installed: setup.sh installs it (apt-get install chromium)")
    return path


@contextlib.contextmanager
def chromium():
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium_path(), args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def open_viewer(browser, url: str, size=(320, 240)):
    """A page showing the viewer at `url`, once it has loaded its GLB and drawn a frame; a load error fails."""
    page = browser.new_page(viewport={"width": size[0], "height": size[1]})
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(url)
    page.wait_for_function("window.prtViewer && window.prtViewer.ready", timeout=120_000)
    state = page.evaluate("window.prtViewer.state()")
    if state["error"] or errors:
        raise RuntimeError(f"the viewer failed: {state['error'] or errors}")
    return page


def viewer_state(page) -> dict:
    return page.evaluate("window.prtViewer.state()")
