"""The README's pictures of `stbs view`, taken in headless Chromium (SwiftShader):
python docs/dev/viewer_screenshots.py [OUT_DIR]   (default docs/images).

Every rig is one the package builds itself: the built-in examples of `stbs view
--example arm|picture` and the 3D character of `stbs.demo.models.character` (the
paper's Fig. 6), rigged with heat bone and endpoint weights."""

from __future__ import annotations

import sys
from pathlib import Path

from playwright.sync_api import sync_playwright

from stbs.cli.view import _example
from stbs.viewer import ViewerServer

ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--headless=new",
        "--disable-dev-shm-usage"]
OUT = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/images")


def character_rig():
    """The demo character (15 bones, about 7.4k vertices), heat weights as `stbs rig`."""
    from stbs.demo.models import character
    from stbs.rig import build_rig

    m = character()
    return build_rig(m.V, m.sk, F=m.F, bone="heat", endpoint="heat"), {}


def shoot(browser, make, steps, size=(1100, 640)):
    """Serve the rig ``make()`` gives, run each step's script, then screenshot it.
    A step is (file name, script) or (file name, script, what to do then with the
    page: a function of it)."""
    rig, extras = make()
    with ViewerServer(rig, extras=extras) as srv:
        page = browser.new_page(viewport={"width": size[0], "height": size[1]})
        page.goto(srv.url)
        page.wait_for_function("window.stbsViewer !== undefined")
        page.evaluate("stbsViewer.ready")
        for out, js, *then in steps:
            page.evaluate(js)
            page.evaluate("stbsViewer.idle()")
            for f in then:
                f(page)
            page.screenshot(path=str(OUT / out))
            print("wrote", OUT / out)
        page.close()


# the character: its left arm raised and bent forward, the right arm lowered,
# the head turned, one knee bent
CHARACTER_POSE = """{rotate: {upper_arm_l: {axis: [0, 0, 1], angle: 55},
                              forearm_l: {axis: [0, 1, 0], angle: -40},
                              upper_arm_r: {axis: [0, 0, 1], angle: 20},
                              head: {axis: [0, 1, 0], angle: 20},
                              thigh_r: {axis: [1, 0, 0], angle: -25},
                              shin_r: {axis: [1, 0, 0], angle: 40}}}"""


def pan_left_and_show_help(page):
    """Pan the view (a right drag) so the character stands left of the help overlay,
    which sits in the middle of the page, then press ? to show it."""
    cam = page.evaluate("stbsViewer.camera()")
    x, y = cam["left"] + cam["width"] / 2, cam["top"] + cam["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down(button="right")
    page.mouse.move(x - 0.65 * cam["width"] / 2, y, steps=8)
    page.mouse.up(button="right")
    page.keyboard.press("?")


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS, headless=True)
        shoot(b, lambda: _example("arm"), [
            ("viewer-arm-compare.png",
             """(async () => {
                  await stbsViewer.setPose({rotate: {fore: {axis: [0, 0, 1], angle: 50}},
                                            twist: {fore: [0, 180]}, stretch: {fore: 1.3}});
                  await stbsViewer.setMethod('stbs-dqs');
                  await stbsViewer.setCompare('lbs');
                  await stbsViewer.frame();
                })()"""),
        ])
        shoot(b, lambda: _example("picture"), [
            ("viewer-picture.png",
             """(async () => {
                  await stbsViewer.setPose({rotate: {upper_arm_r: {angle: -30},
                      forearm_r: {angle: -25}, upper_arm_l: {angle: 25},
                      forearm_l: {angle: 30}, head: {angle: 12}, thigh_l: {angle: -12},
                      thigh_r: {angle: 10}, shin_r: {angle: 15}},
                      stretch: {head: 1.15, forearm_r: 1.35}});
                  await stbsViewer.frame();
                })()"""),
            ("viewer-picture-endpoint.png",
             """(async () => {
                  await stbsViewer.selectBone('forearm_r');
                  await stbsViewer.setColorMode('endpoint');
                  await stbsViewer.setCompare('lbs');
                  await stbsViewer.frame();
                })()"""),
        ])
        shoot(b, character_rig, size=(1280, 720), steps=[
            ("viewer-character-weight.png",
             f"""(async () => {{
                  await stbsViewer.setPose({CHARACTER_POSE});
                  await stbsViewer.selectBone('upper_arm_l');
                  await stbsViewer.setColorMode('weight');
                  await stbsViewer.setMode('paint');
                  document.getElementById('weights-panel').open = true;
                  await stbsViewer.frame();
                }})()"""),
            ("viewer-character-help.png",
             """(async () => {
                  await stbsViewer.setMode('pose');
                  await stbsViewer.setColorMode('shaded');
                  document.getElementById('weights-panel').open = false;
                  await stbsViewer.frame();
                })()""", pan_left_and_show_help),
        ])
        b.close()


if __name__ == "__main__":
    main()
