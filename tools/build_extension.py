"""Build the installable extension zips: fetch the bundled wheels, validate, build one per Python.

    .venv/bin/python tools/build_extension.py [--output-dir dist] [--split-platforms]

1. Downloads every wheel that blender_manifest.toml lists and wheels/ lacks (pip, binary only,
   no dependencies, for the wheel's own platform and CPython version: 3.11 for Blender 4.2 to
   5.0, 3.13 for Blender 5.1 and later).
2. Runs Blender's own extension tool (`blender_ext.py`, shipped inside the bpy wheel; the same
   code as `blender --command extension`) to validate the manifest, then builds one zip per
   CPython: `lumen_gi-<version>-py311.zip` (Blender 4.2 to 5.0) and `...-py313.zip` (Blender 5.1
   and later); with --split-platforms one per platform and CPython (`...-linux_x64-py313.zip`).
3. Prints the zip paths last, one per line.

Exit codes: 0 built, 1 validation or build failed, 3 a wheel could not be downloaded (offline).
"""
from __future__ import annotations

import argparse
import importlib.util
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXIT_DOWNLOAD_FAILED = 3


def manifest() -> dict:
    with open(ROOT / "blender_manifest.toml", "rb") as fh:
        return tomllib.load(fh)


def pip_platform(wheel_name: str) -> str:
    """The --platform tag pip needs to fetch this exact wheel file."""
    tags = wheel_name[:-len(".whl")].split("-")[-1].split(".")
    for tag in tags:   # prefer the newest manylinux tag of a multi-tagged wheel
        if tag.startswith("manylinux_2_28"):
            return tag
    return tags[-1]


def python_tag(wheel_name: str) -> str:
    """The CPython tag of a wheel file name: 'cp311' of embreex-4.4.0.post1-cp311-cp311-....whl."""
    tag = Path(wheel_name).name[:-len(".whl")].split("-")[-3]
    if not (tag.startswith("cp3") and tag[3:].isdigit()):
        raise ValueError(f"{wheel_name}: expected a CPython 3 tag such as cp311, found {tag!r}")
    return tag


def python_version(wheel_name: str) -> str:
    """The --python-version pip needs for this wheel file (cp313 -> 3.13)."""
    return f"3.{python_tag(wheel_name)[3:]}"


def download_wheels(data: dict) -> list[Path]:
    paths = []
    for rel in data.get("wheels", []):
        path = (ROOT / rel).resolve()
        paths.append(path)
        if path.is_file():
            continue
        name, version = path.name.split("-")[:2]
        cmd = [sys.executable, "-m", "pip", "download", "--only-binary=:all:", "--no-deps",
               "--platform", pip_platform(path.name), "--python-version", python_version(path.name),
               f"{name}=={version}", "-d", str(path.parent)]
        print("+", " ".join(cmd), flush=True)
        proc = subprocess.run(cmd)
        if proc.returncode != 0 or not path.is_file():
            raise DownloadError(f"could not download {path.name} (pip exit {proc.returncode}); "
                                f"are PyPI and the network reachable?")
    return paths


class DownloadError(RuntimeError):
    pass


def blender_ext_tool() -> Path:
    """blender_ext.py inside the installed bpy package, found without importing bpy."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("bpy is not installed in this Python; run with the project's .venv")
    base = Path(list(spec.submodule_search_locations)[0])
    found = sorted(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        raise SystemExit(f"blender_ext.py not found under {base}")
    return found[-1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output-dir", default=str(ROOT / "dist"))
    parser.add_argument("--split-platforms", action="store_true",
                        help="one zip per platform and Python, each with only its own wheels")
    args = parser.parse_args(argv)

    data = manifest()
    try:
        download_wheels(data)
    except DownloadError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_DOWNLOAD_FAILED

    tool = blender_ext_tool()
    out = Path(args.output_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, str(tool), "validate", str(ROOT)]
    print("+", " ".join(cmd), flush=True)
    if subprocess.run(cmd).returncode != 0:
        print("error: blender_ext validate failed", file=sys.stderr)
        return 1
    zips = []
    for tag in python_tags(data):
        with tempfile.TemporaryDirectory(prefix=f"lumen-build-{tag}-") as tmp:
            stage = stage_source(Path(tmp) / data["id"], tag)
            built = Path(tmp) / "zips"
            built.mkdir()
            cmd = [sys.executable, str(tool), "build", "--source-dir", str(stage),
                   "--output-dir", str(built)] + (["--split-platforms"] if args.split_platforms else [])
            print("+", " ".join(cmd), flush=True)
            if subprocess.run(cmd).returncode != 0:
                print(f"error: blender_ext build failed ({tag})", file=sys.stderr)
                return 1
            found = sorted(built.glob(f"{data['id']}-{data['version']}*.zip"))
            if not found:
                print(f"error: blender_ext built no zip for {tag} in {built}", file=sys.stderr)
                return 1
            for z in found:   # lumen_gi-0.1.0[-linux_x64].zip -> lumen_gi-0.1.0[-linux_x64]-py311.zip
                target = out / f"{z.stem}-py{tag[2:]}.zip"
                shutil.move(str(z), target)
                zips.append(target)
    for z in zips:
        print(z)
    return 0


def python_tags(data: dict) -> list[str]:
    """The CPython tags of the manifest's wheels, oldest first: ['cp311', 'cp313']."""
    return sorted({python_tag(w) for w in data.get("wheels", [])}, key=lambda t: int(t[3:]))


def stage_source(stage: Path, tag: str) -> Path:
    """A copy of the source whose manifest lists only the `tag` wheels (and wheels/ only them).

    One zip per Python: Blender 4.2.0 to about 4.2.4 install every wheel of their platform
    whatever its Python, so a zip with cp311 and cp313 embreex ends with the cp313 build over the
    cp311 one there (measured: 4.2.0 cannot import embreex.rtcore_scene). Blender reads the
    Python versions from the wheels' tags, so each zip installs only where its Python runs and
    is refused with a clear message elsewhere."""
    ignore = shutil.ignore_patterns(".git", ".venv", "wheels", "dist", "out", "build", "__pycache__",
                                    ".pytest_cache", "*.blend1")
    shutil.copytree(ROOT, stage, ignore=ignore)
    (stage / "wheels").mkdir()
    for rel in manifest().get("wheels", []):
        name = Path(rel).name
        if python_tag(name) == tag:
            shutil.copy2(ROOT / "wheels" / name, stage / "wheels" / name)
    text = (ROOT / "blender_manifest.toml").read_text(encoding="utf-8")
    kept = [line for line in text.splitlines(keepends=True)
            if not (line.strip().startswith('"./wheels/') and f"-{tag}-" not in line)]
    (stage / "blender_manifest.toml").write_text("".join(kept), encoding="utf-8")
    return stage


if __name__ == "__main__":
    sys.exit(main())
