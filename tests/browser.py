"""Headless Chromium for the tests that look at a page as a person does (the 3D views).

Playwright (the `test` extra) drives Debian's `chromium`: Playwright's own browser download is
blocked on these machines, so `chromium_path` finds a system Chromium, and when there is none
and we are root with apt-get, installs Debian's package once (bounded by INSTALL_TIMEOUT);
otherwise the tests that need it are skipped, saying why. Nothing here is imported by the
library; the fixture `browser` (tests/conftest.py) starts one browser per session.

WebGL runs on SwiftShader (software), so no GPU is needed.
"""
from __future__ import annotations

import os
import shutil
import subprocess
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np
import pytest

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
INSTALL_TIMEOUT = 900    # s, apt-get update + install of chromium and its libraries
ARGS = ["--use-angle=swiftshader", "--use-gl=angle", "--enable-unsafe-swiftshader",
        "--ignore-gpu-blocklist", "--disable-dev-shm-usage"]
VIEWPORT = {"width": 1280, "height": 800}


def find_chromium() -> str | None:
    """$STEWART_CHROMIUM, else the first Chromium on PATH."""
    env = os.environ.get("STEWART_CHROMIUM")
    if env:
        return env if Path(env).is_file() else None
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


def install_chromium() -> str:
    """Debian's chromium via apt-get (root only); the reason it cannot be had otherwise."""
    if os.name != "posix" or os.geteuid() != 0 or shutil.which("apt-get") is None:
        return "no chromium on PATH, and not root with apt-get to install Debian's chromium"
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    for cmd in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", "chromium"]):
        try:
            done = subprocess.run(cmd, env=env, capture_output=True, text=True,
                                  timeout=INSTALL_TIMEOUT, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            return f"'{' '.join(cmd)}' took longer than {INSTALL_TIMEOUT} s"
        if done.returncode != 0:
            tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
            return f"'{' '.join(cmd)}' failed ({done.returncode}): {tail[0]}"
    return ""


def chromium_path() -> str:
    """A Chromium executable, installed if need be; pytest.skip with the reason otherwise."""
    path = find_chromium()
    if path is None:
        reason = install_chromium()
        path = find_chromium()
        if path is None:
            pytest.skip(f"headless Chromium unavailable: {reason or 'installed, not found'}")
    return path


@contextmanager
def launch_browser() -> Iterator[object]:
    """A headless Chromium under Playwright (skips when Playwright or Chromium is missing)."""
    try:
        from playwright.sync_api import sync_playwright  # the test extra
    except ImportError:
        pytest.skip("playwright is not installed (pip install -e '.[test]')")
    path = chromium_path()
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=path, headless=True, args=ARGS)
        try:
            yield browser
        finally:
            browser.close()


def open_view(browser, path: Path, timeout_ms: float = 60_000):
    """A page showing the view file `path`, once its first frame is drawn
    (window.stewartView.ready); page errors are collected in page.errors."""
    page = browser.new_page(viewport=VIEWPORT)
    page.errors = []
    page.on("pageerror", lambda exc: page.errors.append(str(exc)))
    page.goto(Path(path).resolve().as_uri())
    page.wait_for_function("window.stewartView && window.stewartView.ready", timeout=timeout_ms)
    return page


def settle(page) -> None:
    """Wait for two animation frames: the viewer has rendered what was just set."""
    page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")


def canvas_pixels(page) -> np.ndarray:
    """The 3D canvas as an (H, W, 3) uint8 array (a screenshot of the page's canvas element)."""
    from io import BytesIO

    from PIL import Image   # pillow: a dependency of matplotlib

    settle(page)
    png = page.locator("#meshcat-pane canvas").screenshot()
    return np.asarray(Image.open(BytesIO(png)).convert("RGB"))
