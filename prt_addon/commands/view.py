"""`prt view FILE.blend`: exports the baked scene to a temporary folder as glTF (blender.gltf) and serves it with the
browser viewer (the repository's viewer/, not part of the add-on zip) on 127.0.0.1 until Ctrl+C (exit 0) or SIGTERM
(cli: exit 143); either way the folder is removed."""

import functools
from http import HTTPStatus
import http.server
import ipaddress
import os
import re
import stat
import tempfile
import threading
import urllib.parse
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
            threading.Event().wait()  # until Ctrl+C; SIGTERM's cli.Terminated passes on to the command line
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


# What the server serves besides the scene, under the viewer's folder: (folder, with its subfolders), files ending
# in SERVED_SUFFIXES only. The viewer's page and scripts, and three.js's modules (its build and its addons, which
# the import map names and which import one another).
SERVED_FOLDERS = (("", False), ("node_modules/three/build", False), ("node_modules/three/examples/jsm", True))
SERVED_SUFFIXES = (".html", ".js")
_HOST = re.compile(r"(\[[0-9A-Fa-f:.]+\]|[^:\[\]]+)(?::([0-9]{1,5}))?")


def served_files(viewer: Path, scene_path: str) -> dict:
    """Every URL path the server answers, and its file: SERVED_FOLDERS' files (/ is index.html) and the scene at
    /scene.glb. Each is a file inside the viewer's folder once links are resolved (a link out of it is left out),
    named by its path below the folder, so nothing else can be asked for: no folder, no `..`, however encoded."""
    root = os.path.realpath(viewer)
    files = {}
    for folder, below in SERVED_FOLDERS:
        for top, folders, names in os.walk(os.path.join(root, folder)):  # never into a linked folder
            if not below:
                folders.clear()
            for name in names:
                path = os.path.join(top, name)
                real = os.path.realpath(path)
                if name.endswith(SERVED_SUFFIXES) and os.path.commonpath([root, real]) == root \
                        and os.path.isfile(real):
                    files["/" + os.path.relpath(path, root).replace(os.sep, "/")] = real
    files["/"] = files.get("/index.html")
    files["/" + SCENE_NAME] = scene_path
    return files


def loopback_host(values: list, port: int) -> bool:
    """Whether a request's Host headers are one that names this server by a loopback address: localhost,
    127.0.0.0/8 or [::1], with the server's port or none. A page from elsewhere whose name was made to resolve to
    127.0.0.1 (DNS rebinding) sends its own name, and is refused."""
    match = _HOST.fullmatch(values[0].strip()) if len(values) == 1 else None
    if match is None or match[2] is not None and int(match[2]) != port:
        return False
    name = match[1]
    try:
        if name.startswith("["):
            return ipaddress.IPv6Address(name[1:-1]) == ipaddress.IPv6Address("::1")
        return name.lower() == "localhost" or ipaddress.IPv4Address(name).is_loopback
    except ValueError:
        return False


class _Handler(http.server.SimpleHTTPRequestHandler):
    """GET and HEAD of the files `served` names, for a loopback Host only; 403 or 404 in plain text for anything
    else. Nothing logged per request."""

    error_message_format = "%(code)d %(message)s\n"
    error_content_type = "text/plain; charset=utf-8"

    def __init__(self, *args, served, **kwargs):
        self.served = served
        super().__init__(*args, **kwargs)

    def send_head(self):
        """Sends the status and headers; the file to send after them, or None after a refusal."""
        if not loopback_host(self.headers.get_all("Host") or [], self.server.server_address[1]):
            self.send_error(HTTPStatus.FORBIDDEN, "only localhost, 127.0.0.0/8 or [::1] are served")
            return None
        path = self.served.get(urllib.parse.unquote(urllib.parse.urlsplit(self.path).path))
        flags = os.O_RDONLY | getattr(os, "O_BINARY", 0) | getattr(os, "O_NOFOLLOW", 0)
        try:  # the file must still be the one found at the start, not a link put in its place since
            file = os.fdopen(os.open(path, flags), "rb") if path else None
        except OSError:
            file = None
        if file is None or not stat.S_ISREG(os.fstat(file.fileno()).st_mode):
            if file is not None:
                file.close()
            self.send_error(HTTPStatus.NOT_FOUND)
            return None
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", self.guess_type(path))
        self.send_header("Content-Length", str(os.fstat(file.fileno()).st_size))
        self.end_headers()
        return file

    def log_message(self, *args):
        pass


def start_server(viewer: Path, scene_path: str, port: int = 0) -> http.server.ThreadingHTTPServer:
    """Serves the viewer and the export (served_files) on 127.0.0.1 from a daemon thread; stop it with
    stop_server."""
    handler = functools.partial(_Handler, served=served_files(viewer, scene_path))
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
