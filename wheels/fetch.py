"""Downloads into this folder the wheels blender_manifest.toml lists (`wheels`), which the extension's zips bundle,
with pip from the package index, and checks each file against its SHA-256 below; a file already here with the
right hash is kept. The wheels are not in the repository (binary, ~100 MB); setup.sh runs this.

    python wheels/fetch.py

Exit 0, or exit 1 and one line naming the wheel and the problem. Changing a wheel's version means changing the
manifest's list and these hashes together (pip download ... --platform ... --python-version ..., then sha256sum)."""

import hashlib
from pathlib import Path
import subprocess
import sys
import tempfile
import tomllib

HERE = Path(__file__).resolve().parent
MANIFEST = HERE.parent / "blender_manifest.toml"

SHA256 = {
    "embreex-4.4.0.post1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl":
        "2cd0f7d5c6342e6247e31f700761689cae7829454d8c6de0c41e62124a023e1f",
    "embreex-4.4.0.post1-cp313-cp313-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl":
        "83165d2bb0436ab9b07d8e7236a0f2509c7868b3a85f2fbd8c41b4d023e88e38",
    "embreex-4.4.0.post1-cp311-cp311-win_amd64.whl":
        "3df27becf6a12b59f5a469bc5271622e26387d52a15880edd29aa564246e7176",
    "embreex-4.4.0.post1-cp313-cp313-win_amd64.whl":
        "506009885b72923661f2b5cd3decd593b9340e3ef06ddb70763303fc5982253e",
    "embreex-4.4.0.post1-cp311-cp311-macosx_13_0_x86_64.whl":
        "85d9b232805e95be845ee5d77ddea4e6b21c992b7e60fa7bdf4f578b84797a15",
    "embreex-4.4.0.post1-cp313-cp313-macosx_13_0_x86_64.whl":
        "b8bd326b36151373adaad23268b60b39d20ec8a371eb1bae309a31e4ab78ac71",
    "embreex-4.4.0.post1-cp311-cp311-macosx_13_0_arm64.whl":
        "3ed370224566681071f245bbc5104feebee1354097679ab69cb3a70c94633cb3",
    "embreex-4.4.0.post1-cp313-cp313-macosx_13_0_arm64.whl":
        "8e0ec6325caab812cb428da4cecb8905b40c6d5bda386ffb73d44bbf2aa7af56",
}


class FetchError(Exception):
    pass


def manifest_wheels() -> list[str]:
    """The file names of the manifest's wheels, each of which must have a hash here."""
    names = [Path(path).name for path in tomllib.loads(MANIFEST.read_text())["wheels"]]
    for name in names:
        if name not in SHA256:
            raise FetchError(f"{name}: in blender_manifest.toml but without a SHA-256 in wheels/fetch.py")
    return names


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def pip_download_arguments(name: str) -> list[str]:
    """pip's arguments that select exactly the wheel `name` (distribution-version-cpXY-abi-platform[.platform].whl)
    whatever machine this runs on."""
    distribution, version, python_tag, _abi, platforms = name.removesuffix(".whl").split("-")
    if not python_tag.startswith("cp3"):
        raise FetchError(f"{name}: not a CPython 3 wheel")
    arguments = [f"{distribution}=={version}", "--no-deps", "--only-binary=:all:",
                 "--python-version", f"3.{python_tag[3:]}", "--implementation", "cp"]
    for platform in platforms.split("."):
        arguments += ["--platform", platform]
    return arguments


def fetch(name: str) -> str:
    """Makes HERE/name the wheel of that name with its hash; says what it did."""
    target = HERE / name
    if target.is_file() and sha256(target) == SHA256[name]:
        return f"{name}: present"
    with tempfile.TemporaryDirectory(prefix=".download-", dir=HERE) as folder:  # beside: the move is a rename
        done = subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--dest", folder,
                               *pip_download_arguments(name)], capture_output=True, text=True)
        if done.returncode != 0:
            reason = (done.stderr.strip().splitlines() or ["pip download failed"])[-1]
            raise FetchError(f"{name}: {reason}")
        downloaded = Path(folder) / name
        if not downloaded.is_file():
            got = ", ".join(path.name for path in Path(folder).iterdir()) or "nothing"
            raise FetchError(f"{name}: pip downloaded {got} instead")
        if sha256(downloaded) != SHA256[name]:
            raise FetchError(f"{name}: downloaded, but its SHA-256 is not the one in wheels/fetch.py")
        downloaded.replace(target)
    return f"{name}: downloaded"


def main() -> int:
    try:
        for name in manifest_wheels():
            print("fetch:", fetch(name), flush=True)
    except FetchError as error:
        print(f"fetch: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
