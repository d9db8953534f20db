"""The README's pictures of `stbs view`, taken in headless Chromium (SwiftShader):
python docs/dev/viewer_screenshots.py [OUT_DIR]   (default docs/images)."""

from __future__ import annotations

import sys
from pathlib import Path

from playwright.sync_api import sync_playwright

from stbs.cli.view import _example
from stbs.viewer import ViewerServer

ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--headless=new",
        "--disable-dev-shm-usage"]
OUT = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/images")


def shoot(browser, name, steps, size=(1100, 640)):
    rig, extras = _example(name)
    with ViewerServer(rig, extras=extras) as srv:
        page = browser.new_page(viewport={"width": size[0], "height": size[1]})
        page.goto(srv.url)
        page.wait_for_function("window.stbsViewer !== undefined")
        page.evaluate("stbsViewer.ready")
        for out, js in steps:
            page.evaluate(js)
            page.evaluate("stbsViewer.idle()")
            page.screenshot(path=str(OUT / out))
            print("wrote", OUT / out)
        page.close()


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS, headless=True)
        shoot(b, "arm", [
            ("viewer-arm-compare.png",
             """(async () => {
                  await stbsViewer.setPose({rotate: {fore: {axis: [0, 0, 1], angle: 50}},
                                            twist: {fore: [0, 180]}, stretch: {fore: 1.3}});
                  await stbsViewer.setMethod('stbs-dqs');
                  await stbsViewer.setCompare('lbs');
                  await stbsViewer.frame();
                })()"""),
        ])
        shoot(b, "picture", [
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
                  const sel = document.getElementById('bone');
                  const opt = [...sel.options].find((o) => o.textContent === 'forearm_r');
                  sel.value = opt.value;
                  sel.dispatchEvent(new Event('change'));
                  await stbsViewer.setColorMode('endpoint');
                  await stbsViewer.setCompare('lbs');
                  await stbsViewer.frame();
                })()"""),
        ])
        b.close()


if __name__ == "__main__":
    main()
