"""`prt view`'s server answers only a loopback Host (so a web page that made its own name resolve to 127.0.0.1 cannot
read the scene: DNS rebinding) and serves only the viewer's page and scripts, three.js's modules and the exported
scene: no listing, no link out of its folder, no `..`, encoded or not; 403 or 404 in plain text for the rest. SIGTERM
stops it as Ctrl+C does and removes its prt_view_* folder. Requests are raw HTTP on a loopback socket, so that
nothing on the client's side rewrites the Host or the path."""

import os
import signal
import socket

import pytest

from conftest import run_cli, start_cli, wait_until
from prt_addon.commands.view import start_server, stop_server

SECRET = b"a file outside the viewer's folder"


def request(port: int, path: str, host: str | None = "127.0.0.1:{port}", headers=()) -> tuple[int, bytes, bytes]:
    """GET `path` as sent, with this Host header (None: none); (status, headers, body)."""
    lines = [f"GET {path} HTTP/1.1", *([f"Host: {host.format(port=port)}"] if host is not None else []),
             *headers, "Connection: close", "", ""]
    with socket.create_connection(("127.0.0.1", port), timeout=30) as connection:
        connection.sendall("\r\n".join(lines).encode())
        answer = b""
        while chunk := connection.recv(65536):
            answer += chunk
    head, _, body = answer.partition(b"\r\n\r\n")
    return int(head.split()[1]), head, body


def planted_viewer(folder):
    """A viewer's folder as npm leaves it, with links planted in it that point outside it: a script, and a folder
    among three.js's modules. Outside it, a file that must never be served."""
    outside = folder / "outside"
    outside.mkdir()
    (outside / "secret.js").write_bytes(SECRET)
    viewer = folder / "viewer"
    modules = viewer / "node_modules" / "three"
    (modules / "build").mkdir(parents=True)
    (modules / "examples" / "jsm" / "loaders").mkdir(parents=True)
    for path, text in [("index.html", "<html>page</html>"), ("main.js", "// main"), ("package.json", "{}"),
                       ("node_modules/three/build/three.module.js", "// three"),
                       ("node_modules/three/package.json", "{}"),
                       ("node_modules/three/examples/jsm/loaders/GLTFLoader.js", "// loader")]:
        (viewer / path).write_text(text)
    (viewer / "leak.js").symlink_to(outside / "secret.js")
    (modules / "examples" / "jsm" / "linked").symlink_to(outside)
    (modules / "build" / "three.cjs.js").symlink_to(outside / "secret.js")
    scene = folder / "scene.glb"
    scene.write_bytes(b"glTF scene")
    return viewer, scene


@pytest.fixture
def planted(tmp_path):
    viewer, scene = planted_viewer(tmp_path)
    server = start_server(viewer, str(scene))
    yield server.server_address[1], viewer, scene
    stop_server(server)


@pytest.mark.parametrize("host", ["127.0.0.1:{port}", "127.0.0.1", "localhost:{port}", "LocalHost", "127.4.5.6:{port}",
                                  "[::1]:{port}", "[::1]", "[0:0:0:0:0:0:0:1]:{port}"])
def test_a_loopback_host_is_served(planted, host):
    port, viewer, scene = planted
    status, head, body = request(port, "/scene.glb", host)
    assert (status, body) == (200, scene.read_bytes())


@pytest.mark.parametrize("host", ["evil.example:{port}", "evil.example", "127.0.0.1.evil.example:{port}",
                                  "localhost.evil.example", "localhost.:{port}", "127.0.0.1:1", "localhost:{port}0",
                                  "[::2]:{port}", "[::ffff:127.0.0.1]:{port}", "0.0.0.0:{port}", "10.0.0.1:{port}",
                                  "127.1:{port}", "127.0.0.1:{port}:{port}", "user@127.0.0.1:{port}", "", None])
def test_any_other_host_is_refused_with_403(planted, host):
    """A rebinding page sends its own name (evil.example), with the server's port or without."""
    port, _, _ = planted
    status, head, body = request(port, "/scene.glb", host)
    assert status == 403 and b"Content-Type: text/plain" in head and b"glTF" not in body


def test_two_host_headers_are_refused(planted):
    port, _, _ = planted
    status, _, body = request(port, "/scene.glb", headers=["Host: evil.example"])
    assert status == 403 and b"glTF" not in body


def test_only_the_viewers_files_three_js_and_the_scene_are_served(planted):
    port, viewer, scene = planted
    for path, expected in [("/", "index.html"), ("/index.html", "index.html"), ("/main.js", "main.js"),
                           ("/main.js?v=1", "main.js"), ("/node_modules/three/build/three.module.js", None),
                           ("/node_modules/three/examples/jsm/loaders/GLTFLoader.js", None), ("/%6Dain.js", "main.js")]:
        status, head, body = request(port, path)
        assert status == 200, path
        assert body == (viewer / (expected or path[1:])).read_bytes(), path
    assert b"Content-Type: text/javascript" in request(port, "/main.js")[1]
    for path in ["/node_modules/", "/node_modules", "/node_modules/three/", "/node_modules/three/build/",
                 "/node_modules/three/examples/jsm/", "/package.json", "/node_modules/three/package.json",
                 "/scene.glb/", "/index.html/", "/nothing.js"]:
        status, head, body = request(port, path)
        assert status == 404 and b"Content-Type: text/plain" in head and b"<" not in body, path


def test_links_out_of_the_folder_are_not_followed(planted):
    port, _, _ = planted
    for path in ["/leak.js", "/node_modules/three/examples/jsm/linked/secret.js",
                 "/node_modules/three/build/three.cjs.js"]:
        status, _, body = request(port, path)
        assert status == 404 and SECRET not in body, path


def test_a_link_put_in_place_of_a_served_file_is_not_followed(planted):
    port, viewer, _ = planted
    main = viewer / "main.js"
    main.unlink()
    main.symlink_to(viewer.parent / "outside" / "secret.js")
    status, _, body = request(port, "/main.js")
    assert status == 404 and SECRET not in body


@pytest.mark.parametrize("path", ["/../outside/secret.js", "/%2e%2e/outside/secret.js", "/%2E%2E%2Foutside%2Fsecret.js",
                                  "/node_modules/three/build/%2e%2e/%2e%2e/%2e%2e/%2e%2e/outside/secret.js",
                                  "/..%2f..%2foutside/secret.js", "/%252e%252e/outside/secret.js",
                                  "//%2e%2e/outside/secret.js", "/.%2e/outside/secret.js",
                                  "/node_modules/three/examples/jsm/../../../../../outside/secret.js",
                                  "http://127.0.0.1/../outside/secret.js"])
def test_traversal_encoded_or_not_is_refused(planted, path):
    port, _, _ = planted
    status, _, body = request(port, path)
    assert status == 404 and SECRET not in body


# -- the command ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def baked(tmp_path_factory, sample_scene_files):
    path = tmp_path_factory.mktemp("view") / "suzanne.blend"
    path.write_bytes((sample_scene_files / "suzanne.blend").read_bytes())
    done = run_cli("bake", path, "--order", "2", "--samples", "8")
    assert done.returncode == 0, done.stderr
    return path


def test_prt_view_refuses_forged_hosts_listings_and_traversal_and_sigterm_removes_its_folder(baked, tmp_path):
    before = baked.read_bytes()
    process = start_cli(["view", baked], tmp_path)
    try:
        said = wait_until(lambda: [line for line in (tmp_path / "stdout.txt").read_text().splitlines()
                                   if "viewer at http://127.0.0.1:" in line], "viewer's address", process)
        port = int(said[0].split("http://127.0.0.1:")[1].split("/")[0])
        assert [name[:9] for name in os.listdir(tmp_path / "tmp") if name.startswith("prt_view_")] == ["prt_view_"]
        status, _, body = request(port, "/index.html")
        assert status == 200 and b"importmap" in body
        status, _, body = request(port, "/scene.glb", "localhost:{port}")
        assert status == 200 and body[:4] == b"glTF"
        assert request(port, "/node_modules/three/build/three.module.js")[0] == 200
        assert request(port, "/scene.glb", "rebound.example:{port}")[0] == 403
        for path in ["/node_modules/", "/node_modules/three/", "/%2e%2e/%2e%2e/prt_addon/__init__.py",
                     "/../prt_addon/__init__.py", "/package.json"]:
            assert request(port, path)[0] == 404, path
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=60)
    finally:
        process.kill()
        process.wait()
    errors = (tmp_path / "stderr.txt").read_text()
    assert process.returncode == 143, errors
    assert [line for line in errors.splitlines() if line.startswith("prt:")] == \
        ["prt: error: terminated (SIGTERM); nothing was written"]
    assert os.listdir(tmp_path / "tmp") == []  # neither prt_view_* nor the bpy module's blender_*
    assert baked.read_bytes() == before
