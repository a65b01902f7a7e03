"""Build the installable extension zip: fetch the bundled wheels, validate, build.

    .venv/bin/python tools/build_extension.py [--output-dir dist] [--split-platforms]

1. Downloads every wheel that blender_manifest.toml lists and wheels/ lacks (pip, binary only,
   no dependencies, for the wheel's own platform and CPython version: 3.11 for Blender 4.2 to
   5.0, 3.13 for Blender 5.1 and later).
2. Runs Blender's own extension tool (`blender_ext.py`, shipped inside the bpy wheel; the same
   code as `blender --command extension`) to validate the manifest and build the zip.
3. Prints the zip path(s) last, one per line.

Exit codes: 0 built, 1 validation or build failed, 3 a wheel could not be downloaded (offline).
"""
from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
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


def python_version(wheel_name: str) -> str:
    """The --python-version pip needs for this wheel file: its cpXY tag (cp313 -> 3.13)."""
    tag = wheel_name[:-len(".whl")].split("-")[-3]
    if not (tag.startswith("cp3") and tag[3:].isdigit()):
        raise ValueError(f"{wheel_name}: expected a CPython 3 tag such as cp311, found {tag!r}")
    return f"3.{tag[3:]}"


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
                        help="one zip per platform, each with only its own wheels")
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
    before = set(out.glob("*.zip"))
    steps = [["validate", str(ROOT)],
             ["build", "--source-dir", str(ROOT), "--output-dir", str(out)]
             + (["--split-platforms"] if args.split_platforms else [])]
    for step in steps:
        cmd = [sys.executable, str(tool), *step]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd).returncode != 0:
            print(f"error: blender_ext {step[0]} failed", file=sys.stderr)
            return 1
    if args.split_platforms:
        zips = sorted(out.glob(f"{data['id']}-{data['version']}-*.zip"))
    else:
        zips = [out / f"{data['id']}-{data['version']}.zip"]
    missing = [z for z in zips if not z.is_file()]
    if not zips or missing:
        print(f"error: expected zip not built in {out} (new files: "
              f"{sorted(map(str, set(out.glob('*.zip')) - before))})", file=sys.stderr)
        return 1
    for z in zips:
        print(z)
    return 0


if __name__ == "__main__":
    sys.exit(main())
