"""viewer.png: the browser viewer (viewer/) showing the demo bake in Debian's chromium, headless through Playwright
(tests/browser.py: WebGL 2 on the CPU). As `prt view` does (commands.view), the baked file is exported as glTF with
the web profile and served with the viewer on 127.0.0.1; the page loads it and draws it under the export's SH
lights, its sun aimed where relight.png's second render has it (the page's theta and phi parameters,
commands.demo.MOVED_SUN) and the light vectors shown (the L key), so the sun's direction is on screen; the server
stops after.

Printed, and read back by tests/test_figures.py: the export's line, and what the viewer says it drew (vertices,
lights and where the active one shines from, from its window.prtViewer.state()).
"""

import math
import os

import bpy

from browser import chromium, open_viewer, viewer_state
from figures_common import save_png
from prt_addon.blender import gltf
from prt_addon.commands.common import open_file
from prt_addon.commands.demo import MOVED_SUN
from prt_addon.commands.export import gltf_summary
from prt_addon.commands.view import SCENE_NAME, address, start_server, stop_server, viewer_folder

NAME = "viewer.png"
SIZE = {"full": (1200, 750), "quick": (480, 300)}


def make(run) -> str:
    viewer = viewer_folder()
    open_file(run.demo_blend(), required=True)
    scene_path = os.path.join(run.scratch, SCENE_NAME)
    print(f"viewer: {gltf_summary(gltf.export(bpy.context.scene, scene_path, 'web'))}")
    screenshot = os.path.join(run.scratch, "viewer_screenshot.png")
    server = start_server(viewer, scene_path)
    try:
        with chromium() as browser:
            theta, phi = MOVED_SUN
            page = open_viewer(browser, f"{address(server)}?theta={theta:g}&phi={phi:g}", run.pick(SIZE))
            page.keyboard.press("l")  # the light vectors: the sun's arrow
            state = viewer_state(page)
            page.screenshot(path=screenshot)
    finally:
        stop_server(server)
    sun = state["lights"][state["active"]]
    print(f"viewer: drew {state['vertices']} vertices under {len(state['lights'])} lights, the active one a "
          f"{sun['kind']} at θ {math.degrees(sun['theta']):.1f}°, φ {math.degrees(sun['phi']):.1f}°, light vectors "
          f"{'on' if state['vectors'] else 'off'}")
    return save_png(screenshot, run.path(NAME))
