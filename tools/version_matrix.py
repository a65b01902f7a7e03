"""The Blender version matrix: install the built zip in each supported Blender, bake, render F12.

    .venv/bin/python tools/version_matrix.py [--out DIR] [--legs 4.2.0,5.3.0-vulkan]

Each leg is a Blender (as the `bpy` module, in its own virtual environment under
.venv/versions/, created on first use with the CPython it needs) and a GPU backend. Every leg runs
tools/smoke_install.py in a clean user folder: install this platform's zip for the leg's Python
(built first by build_extension.py --split-platforms), enable it, bake the demo scene,
F12. The images are compared with the 5.0.1 (development) leg's: relMSE = mean((a - b)^2) /
mean(b^2) over RGB. A leg whose CPython is not on this machine is skipped with the reason; the
Vulkan leg is skipped where Mesa's lavapipe (Debian: mesa-vulkan-drivers) is not installed.

Vulkan is Blender's choice from 5.1 on wherever a Vulkan driver exists; the OpenGL legs hide the
Vulkan drivers from the loader (VK_DRIVER_FILES / VK_ICD_FILENAMES pointing at nothing), which makes
Blender fall back to OpenGL exactly as on a machine without Vulkan.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ENVS = ROOT / ".venv" / "versions"
REFERENCE = "5.0.1"
NO_VULKAN = {"VK_DRIVER_FILES": os.devnull, "VK_ICD_FILENAMES": os.devnull}


@dataclass(frozen=True)
class Leg:
    name: str                  # "4.2.0", "5.3.0-vulkan"
    bpy: str                   # the bpy version on the package index
    python: str                # the CPython it is built for
    backend: str               # the GPU backend the leg must run on
    extra: tuple = ()          # more pins: the numpy that Blender release bundles
    env: dict = field(default_factory=dict, hash=False)


LEGS = (
    # oldest supported: Blender 4.2 LTS bundles numpy 1.26 (the bpy wheel leaves it unpinned)
    Leg("4.2.0", "4.2.0", "3.11", "OPENGL", ("numpy==1.26.4",), NO_VULKAN),
    Leg(REFERENCE, REFERENCE, "3.11", "OPENGL", (), NO_VULKAN),
    Leg("5.3.0", "5.3.0", "3.13", "OPENGL", (), NO_VULKAN),
    Leg("5.3.0-vulkan", "5.3.0", "3.13", "VULKAN"),
)


class LegSkipped(Exception):
    """The leg cannot run on this machine (its CPython or GPU driver is absent)."""


def find_python(version: str) -> str | None:
    """A CPython `version` ("3.13") executable: on PATH, else pyenv's, else None."""
    for cand in (shutil.which(f"python{version}"),):
        if cand and _is_version(cand, version):
            return cand
    roots = [os.environ.get("PYENV_ROOT", ""), str(Path.home() / ".pyenv")]
    for root in filter(None, roots):
        for cand in sorted(glob.glob(f"{root}/versions/{version}*/bin/python{version}"), reverse=True):
            if _is_version(cand, version):
                return cand
    return None


def _is_version(exe: str, version: str) -> bool:
    try:
        out = subprocess.run([exe, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"],
                             capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return False
    return out.returncode == 0 and out.stdout.strip() == version


def lavapipe_installed() -> bool:
    dirs = ["/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d"]
    return any(glob.glob(f"{d}/lvp_icd*.json") for d in dirs)


def ensure_env(leg: Leg, log=print) -> str:
    """The Python of the leg's virtual environment, created and filled on first use."""
    if leg.bpy == REFERENCE and sys.version_info[:2] == (3, 11) and _has_bpy(sys.executable, REFERENCE):
        return sys.executable                                  # the project's own .venv
    env_dir = ENVS / f"bpy-{leg.bpy}"
    py = env_dir / "bin" / "python"
    stamp = env_dir / ".installed"
    want = " ".join((f"bpy=={leg.bpy}",) + leg.extra)
    if py.is_file() and stamp.is_file() and stamp.read_text() == want:
        return str(py)
    base = find_python(leg.python)
    if base is None:
        raise LegSkipped(f"bpy {leg.bpy} needs CPython {leg.python}, which is not on this machine "
                         f"(PATH or pyenv)")
    log(f"creating {env_dir} (CPython {leg.python}, {want}; downloads ~400 MB once)")
    if env_dir.exists():
        shutil.rmtree(env_dir)
    subprocess.run([base, "-m", "venv", str(env_dir)], check=True)
    subprocess.run([str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check",
                    *want.split()], check=True)
    stamp.write_text(want)
    return str(py)


def _has_bpy(exe: str, version: str) -> bool:
    out = subprocess.run([exe, "-c", "import importlib.metadata as m; print(m.version('bpy'))"],
                         capture_output=True, text=True)
    return out.returncode == 0 and out.stdout.strip() == version


def run_leg(leg: Leg, zip_path: str, out: Path, log=print) -> dict:
    """Install, bake, F12 in a clean user folder; returns the smoke report plus 'seconds',
    'image' (path of the .npy) and 'log' (the last output lines)."""
    if leg.backend == "VULKAN" and not lavapipe_installed():
        raise LegSkipped("no Vulkan driver: install Mesa's lavapipe (Debian: mesa-vulkan-drivers)")
    py = ensure_env(leg, log)
    out.mkdir(parents=True, exist_ok=True)
    user = Path(tempfile.mkdtemp(prefix="lumen-user-", dir=out))
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(user), PYTHONDONTWRITEBYTECODE="1", **leg.env)
    t0 = time.perf_counter()
    proc = subprocess.run([py, str(ROOT / "tools" / "smoke_install.py"), str(zip_path),
                           "--out", str(out)], capture_output=True, text=True, env=env, timeout=900)
    seconds = time.perf_counter() - t0
    text = proc.stdout + proc.stderr
    report_file = out / "report.json"
    report = json.loads(report_file.read_text()) if report_file.is_file() else {}
    report.update(seconds=seconds, returncode=proc.returncode, image=str(out / "render.npy"),
                  log="\n".join(text.splitlines()[-40:]),
                  push_constant_warnings=text.count("Push constants have a minimum supported size"))
    return report


def rel_mse(image, reference) -> float:
    import numpy as np
    a = np.asarray(image, np.float64)[..., :3]
    b = np.asarray(reference, np.float64)[..., :3]
    return float(((a - b) ** 2).mean() / max((b ** 2).mean(), 1e-30))


def build_zips() -> dict:
    """{"3.11": zip, "3.13": zip}: this platform's zips from build_extension.py --split-platforms."""
    import sysconfig
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "build_extension.py"),
                           "--split-platforms"], capture_output=True, text=True, timeout=900)
    if proc.returncode != 0:
        raise RuntimeError(proc.stdout[-2000:] + proc.stderr[-2000:])
    plat = {"linux-x86_64": "linux_x64", "win-amd64": "windows_x64",
            "macosx-arm64": "macos_arm64", "macosx-x86_64": "macos_x64"}
    key = sysconfig.get_platform()
    key = "macosx-" + key.rsplit("-", 1)[-1] if key.startswith("macosx") else key
    zips = {}
    for line in proc.stdout.splitlines():        # the zip paths are printed last, one per line
        path = Path(line.strip())
        if path.is_absolute() and path.suffix == ".zip" and f"-{plat.get(key, '?')}-py" in path.name:
            tag = path.stem.rsplit("-py", 1)[1]     # "311"
            zips[f"{tag[0]}.{tag[1:]}"] = str(path)
    if not zips:
        raise RuntimeError(f"no zip for platform {key} in: {proc.stdout}")
    return zips


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(ROOT / "out" / "versions"))
    parser.add_argument("--legs", help="comma-separated leg names (default: all)")
    args = parser.parse_args(argv)
    zips = build_zips()
    names = args.legs.split(",") if args.legs else [leg.name for leg in LEGS]
    if REFERENCE not in names:
        names.insert(0, REFERENCE)
    legs = sorted((leg for leg in LEGS if leg.name in names), key=lambda l: l.name != REFERENCE)
    import numpy as np
    reference, failed = None, False
    print(f"{'leg':14} {'blender':12} {'python':8} {'backend':8} {'seconds':>8} {'relMSE vs ' + REFERENCE:>16}")
    for leg in legs:
        try:
            if leg.python not in zips:
                raise LegSkipped(f"no zip was built for CPython {leg.python}")
            rep = run_leg(leg, zips[leg.python], Path(args.out) / leg.name,
                          log=lambda m: print(m, file=sys.stderr))
        except LegSkipped as exc:
            print(f"{leg.name:14} skipped: {exc}")
            continue
        ok = rep["returncode"] == 0 and rep.get("gpu_backend") == leg.backend \
            and not rep["push_constant_warnings"]
        err = ""
        if ok:
            img = np.load(rep["image"])
            if reference is None:
                reference = img
            err = f"{rel_mse(img, reference):.2e}"
        else:
            failed = True
            print(rep["log"], file=sys.stderr)
            err = rep.get("error") or f"exit {rep['returncode']}, backend {rep.get('gpu_backend')}"
        print(f"{leg.name:14} {rep.get('blender', '?'):12} {rep.get('python', '?'):8} "
              f"{rep.get('gpu_backend', '?'):8} {rep['seconds']:8.1f} {err:>16}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
