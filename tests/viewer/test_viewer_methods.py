"""The skinning methods' names reach the page from the server only (``methods`` of
``GET /api/rig``, the library's ``stbs.methods.SKINNING_METHODS``); the page checks
them against the order of its shader's ``uMethod`` values (viewer/src/skin.js
``checkMethods``) and refuses to load otherwise. Headless Chromium through
Playwright; rigs and the page helper: test_viewer_page.py."""

from __future__ import annotations

import pytest
from test_viewer_page import (  # noqa: F401  (fixture)
    READY_S,
    Page,
    browser,
    tube_rig,
)

from stbs.methods import SKINNING_METHODS
from stbs.viewer import ViewerServer


def test_the_page_takes_the_servers_methods_for_its_menus(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    try:
        assert p.info["methods"] == list(SKINNING_METHODS)
        menus = p.js("""() => ['method', 'compare'].map((id) =>
            [...document.getElementById(id).options].map((o) => o.value).filter(Boolean))""")
        assert menus == [list(SKINNING_METHODS)] * 2
        p.js("stbsViewer.setCompare('lbs')")
        assert p.js("stbsViewer.compare()") == "lbs"
        labels = p.js("[...document.querySelectorAll('#compare-labels span')]"
                      ".map((s) => s.textContent)")
        assert labels == ["stbs-dqs", "lbs"]
        err = p.js("stbsViewer.setCompare('cor').then(() => 'ok', (e) => e.message)")
        assert "one of lbs, dqs, stbs-lbs, stbs-dqs" in err and '"cor"' in err, err
        err = p.js("stbsViewer.setMethod('cor').then(() => 'ok', (e) => e.message)")
        assert "one of lbs, dqs, stbs-lbs, stbs-dqs" in err and '"cor"' in err, err
        assert p.errors == []
    finally:
        p.close()


@pytest.mark.parametrize("sent", [["dqs", "lbs", "stbs-lbs", "stbs-dqs"],
                                  ["lbs", "dqs", "stbs-lbs"]])
def test_methods_in_another_order_than_the_shaders_stop_the_page_with_one_line(
        browser, monkeypatch, sent):  # noqa: F811
    monkeypatch.setattr("stbs.viewer.payload.METHODS", tuple(sent))
    srv = ViewerServer(tube_rig()).start()
    try:
        page = browser.new_page(viewport={"width": 640, "height": 480})
        page.goto(srv.url)
        page.wait_for_function("window.stbsViewer !== undefined", timeout=READY_S * 1000)
        err = page.evaluate("stbsViewer.ready.then(() => 'ready', (e) => e.message)")
        assert err != "ready"
        assert '"methods" of /api/rig' in err, err
        assert '["lbs","dqs","stbs-lbs","stbs-dqs"]' in err and str(sent).replace(
            "'", '"').replace(" ", "") in err, err
        page.wait_for_function("() => document.querySelector('#status.error') !== null",
                               timeout=READY_S * 1000)
        assert '"methods" of /api/rig' in page.text_content("#status")
        page.close()
    finally:
        srv.shutdown()
