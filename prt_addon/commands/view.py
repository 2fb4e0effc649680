"""`prt view FILE.blend`: exports the baked scene to a temporary folder as glTF (blender.gltf) and serves it with the
browser viewer (the repository's viewer/, not part of the add-on zip) on 127.0.0.1 until Ctrl+C."""

import functools
import http.server
import os
import tempfile
import threading
from pathlib import Path

import bpy

from ..blender import gltf
from ..core.errors import InputError
from ..core.gltf_pack import PROFILES
from .common import open_file
from .export import gltf_summary

VIEWER = Path(__file__).resolve().parents[2] / "viewer"
SCENE_NAME = "scene.glb"  # what the viewer loads by default


def add_parser(commands):
    parser = commands.add_parser("view", help="relight the baked scene live in a browser (the viewer in viewer/)")
    parser.add_argument("file", help=".blend file with a bake")
    parser.add_argument("--profile", choices=list(PROFILES), default="web", help="glTF packing, as prt export's")
    parser.add_argument("--port", type=int, default=0, help="port on 127.0.0.1 (default: any free one)")


def run(args, in_blender: bool) -> int:
    viewer = viewer_folder()
    open_file(args.file, required=True)
    with tempfile.TemporaryDirectory(prefix="prt_view_") as folder:
        scene_path = os.path.join(folder, SCENE_NAME)
        print(f"prt: {gltf_summary(gltf.export(bpy.context.scene, scene_path, args.profile))}")
        server = start_server(viewer, scene_path, args.port)
        print(f"prt: viewer at {address(server)} (Ctrl+C stops)", flush=True)
        try:
            threading.Event().wait()  # until Ctrl+C
        except KeyboardInterrupt:
            print("prt: viewer stopped")
        finally:
            stop_server(server)
    return 0


def viewer_folder() -> Path:
    """The viewer with its three.js installed; a checkout has it (setup.sh runs npm install there)."""
    if not (VIEWER / "index.html").is_file():
        raise InputError(f"no viewer at {VIEWER}: prt view runs from a checkout of the repository, not the add-on zip")
    if not (VIEWER / "node_modules" / "three" / "build" / "three.module.js").is_file():
        raise InputError(f"three.js is not installed in {VIEWER}: run npm install there (setup.sh does)")
    return VIEWER


class _Handler(http.server.SimpleHTTPRequestHandler):
    """The viewer's files, and /scene.glb from the export's folder; nothing logged per request."""

    def __init__(self, *args, scene_path, **kwargs):
        self.scene_path = scene_path
        super().__init__(*args, **kwargs)

    def translate_path(self, path):
        if path.split("?", 1)[0] == "/" + SCENE_NAME:
            return self.scene_path
        return super().translate_path(path)

    def log_message(self, *args):
        pass


def start_server(viewer: Path, scene_path: str, port: int = 0) -> http.server.ThreadingHTTPServer:
    """Serves the viewer and the export on 127.0.0.1 from a daemon thread; stop it with stop_server."""
    handler = functools.partial(_Handler, directory=str(viewer), scene_path=scene_path)
    server = http.server.ThreadingHTTPServer(("127.0.0.1", port), handler)
    # Stopping does not wait for requests still being answered (a browser may hold a connection open): their
    # threads are daemons and end with the process.
    server.block_on_close = False
    threading.Thread(target=server.serve_forever, name="prt viewer server", daemon=True).start()
    return server


def stop_server(server):
    server.shutdown()
    server.server_close()


def address(server) -> str:
    host, port = server.server_address[:2]
    return f"http://{host}:{port}/index.html"
