"""The page without its script: the fallback text of static/index.html says what is
missing and how to get a page, without an npm command (an installed package has no
viewer/ to run it in). Headless Chromium through Playwright on a copy of the static
folder without viewer.js; the page helper: test_viewer_page.py."""

from __future__ import annotations

import shutil

from test_viewer_page import browser, tube_rig  # noqa: F401  (fixture)

from stbs.viewer import STATIC_DIR, ViewerServer


def test_without_its_script_the_page_says_how_to_install_it(browser, tmp_path):  # noqa: F811
    static = tmp_path / "static"
    static.mkdir()
    for name in ("index.html", "viewer.css"):
        shutil.copyfile(STATIC_DIR / name, static / name)
    with ViewerServer(tube_rig(), static_dir=static) as srv:
        page = browser.new_page(viewport={"width": 640, "height": 480})
        page.goto(srv.url)
        page.wait_for_load_state("load")
        box = page.locator("#fallback").bounding_box()
        assert box is not None and box["width"] >= 600 and box["height"] >= 400, box
        text = " ".join(page.text_content("#fallback").split())
        page.close()
    assert "missing from this installation, or JavaScript is off" in text, text
    assert "from a wheel or the sdist (both include the page)" in text, text
    assert "with Node.js and npm, where pip install . (or make install) builds it" in text, text
    assert "npm ci" not in text and "npm run" not in text, text
    assert "viewer-api.md" in text, text
