"""read_cache against hostile caches: well over 1,000 mutations of one small real cache.

Each mutated cache must either be refused with CacheError (naming a file of the cache, never
the reader's "internal error") or read back exactly the original content, within a bounded time
(a hang guard, not a benchmark) and bounded memory (traced allocations). Nothing else may escape.

Mutations: truncations, appended bytes and byte flips of every file; the same "resealed" (the
file renamed to its content name and the manifest given its new size and SHA-256, as a crafted
cache would be); edited manifest values (NaN, infinities, huge, negative, zero, wrong types,
missing keys, extra keys and entries, dropped entries, over-long strings); raw JSON oddities;
swapped files and swapped names; symlinks to /dev/zero, FIFOs, directories and huge sparse files
in place of files; crafted .npz files (decompression bombs, headers declaring huge shapes,
patched zip directories, pickled objects, out-of-range indices) and crafted images (wrong
size, channels, pixel type, NaN texels, tiled, another format, a data window of 2^30 rows).

Some mutations give a different but equally valid cache (a manifest byte flip that turns a
matrix entry 0.5 into 0.4): those cannot be refused by any reader and are counted apart as
"plausible"; they must still be refused or read without escaping, in bounded time and memory.
"""
import copy
import dataclasses
import hashlib
import io
import json
import os
import re
import resource
import shutil
import signal
import struct
import tempfile
import time
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

import shapes
from lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_addon.cache import INTERNAL, MANIFEST, MAX_MANIFEST_BYTES, CacheError, read_cache, write_cache
from lumen_addon.materials import Material

SEED = 11
HANG_SECONDS = 20.0        # a case still running after this is a hang (normal: milliseconds)
CASE_SECONDS = 5.0         # and every case must finish within this
CASE_PEAK_BYTES = 64 << 20     # traced allocation peak of one read (this cache is ~30 kB)
RSS_GROWTH_BYTES = 300 << 20   # growth of the process's peak RSS over the whole run
MIN_CASES = 1000

# Manifest values where another in-range value is a different valid cache (no reader can tell):
# byte flips that only change these are "plausible", not attacks.
VALUE_FREE = re.compile(r"(instances\[\d+\]\.matrix_world\[\d+\]\[\d+\]"
                        r"|meshes\[\d+\]\.(origin|bounds_min|bounds_max|requested_resolution)\[\d+\]"
                        r"|atlas\.cards\[\d+\]\.(rect_min\[\d+\]|rect_max\[\d+\]|rect\[\d+\]|near|far|axis)"
                        r"|settings\.\w+|atlas\.coverage\.\w+|atlas\.padding"
                        r"|stats\.(seconds|reused))$")
# ... and where zero or a negative number is valid, so "zero" and "neg" edits are not made.
SIGN_FREE = re.compile(r"(instances\[\d+\]\.matrix_world\[\d+\]\[\d+\]"
                       r"|meshes\[\d+\]\.(origin|bounds_min|bounds_max)\[\d+\]"
                       r"|atlas\.cards\[\d+\]\.(rect_min\[\d+\]|rect_max\[\d+\]|near|far|axis)"
                       r"|settings\.(inside_fraction|min_card_size)|atlas\.coverage\.\w+|atlas\.padding"
                       r"|stats\.(seconds|reused))$")
# ... and keys a manifest may leave out (older caches have none: read with their old meaning).
OPTIONAL = re.compile(r"^settings\.min_card_size$")


class Hung(BaseException):
    """Raised by the hang guard's timer (a BaseException: no reader's `except Exception` eats it)."""


# -- the cache under test -----------------------------------------------------------------------

@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """(files {name: bytes}, manifest dict, the read-back bake) of one small real cache."""
    sv, sf = shapes.icosphere(0.5, 2)
    bv, bf = shapes.box()
    glow = Material(base_color=(0.9, 0.2, 0.1), emission_color=(1, 1, 1), emission_strength=3.0)
    objs = [ObjectInput("Sphere", sv, sf), ObjectInput("Sphere.001", sv, sf, np.diag([1.1, 1.1, 1.1, 1])),
            ObjectInput("Box", bv, bf, two_sided=True, materials=[glow])]
    bake = bake_scene(objs, BakeSettings(voxel_density=6, texel_density=8))
    folder = tmp_path_factory.mktemp("original")
    write_cache(folder, bake)
    files = {p.name: p.read_bytes() for p in folder.iterdir() if not p.name.startswith(".")}
    return files, json.loads(files[MANIFEST]), read_cache(folder)


def difference(a, b, path="bake"):
    """The first difference between two read-back bakes (types, dtypes and values), or None."""
    if type(a) is not type(b):
        return f"{path}: {type(a).__name__} != {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            d = difference(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")
            if d:
                return d
        return None
    if isinstance(a, np.ndarray):
        ok = a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
        return None if ok else f"{path}: arrays differ"
    if isinstance(a, dict):
        if list(a) != list(b):
            return f"{path}: keys differ"
        return next((d for k in a if (d := difference(a[k], b[k], f"{path}[{k!r}]"))), None)
    if isinstance(a, (list, tuple)):
        if len(a) != len(b):
            return f"{path}: lengths differ"
        return next((d for i, (x, y) in enumerate(zip(a, b)) if (d := difference(x, y, f"{path}[{i}]"))),
                    None)
    return None if a == b else f"{path}: {a!r} != {b!r}"


def test_difference_sees_every_field(original):
    """The oracle itself: a change anywhere in a bake is seen."""
    _, _, bake = original
    assert difference(bake, copy.deepcopy(bake)) is None
    for change in (lambda b: b.instances[1].matrix_world.__setitem__((0, 3), 0.25),
                   lambda b: next(iter(b.meshes.values())).mips[2].bricks.__setitem__((0, 1, 2, 3), 9),
                   lambda b: setattr(next(iter(b.meshes.values())), "two_sided", True),
                   lambda b: b.atlas.layers["depth"].__setitem__((3, 5, 0), 0.5),
                   lambda b: b.atlas.table[3].__setitem__("near", 0.1),
                   lambda b: setattr(b, "seconds", 1.0)):
        other = copy.deepcopy(bake)
        change(other)
        assert difference(bake, other) is not None


# -- running one case ---------------------------------------------------------------------------

class Fuzzer:
    def __init__(self, folder: Path, files: dict, manifest: dict, baseline):
        self.folder, self.files, self.manifest, self.baseline = folder, files, manifest, baseline
        self.counts = {"refused": 0, "identical": 0, "plausible": 0}
        self.problems, self.slowest, self.peak = [], (0.0, ""), (0, "")

    def reset(self):
        for entry in os.scandir(self.folder):
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path)
            else:
                os.unlink(entry.path)
        for name, data in self.files.items():
            (self.folder / name).write_bytes(data)

    def case(self, label: str, mutate, plausible: bool = False, expect: str = None):
        """Reset the folder, mutate it, read it; record what came out. plausible: the mutation may
        give a different valid cache, so a successful read is not compared. expect: "refused" or
        "identical" where the mutation's outcome is known."""
        self.reset()
        mutate(self.folder)
        tracemalloc.reset_peak()
        before = tracemalloc.get_traced_memory()[0]
        start = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, HANG_SECONDS)
        outcome, msg = None, ""
        try:
            got = read_cache(self.folder)
            outcome = "plausible" if plausible else "identical"
            if not plausible and (d := difference(self.baseline, got)):
                self.problems.append(f"{label}: read a different cache ({d})")
        except CacheError as exc:
            outcome, msg = "refused", str(exc)
            if INTERNAL in msg or not msg.startswith(str(self.folder)):
                self.problems.append(f"{label}: {msg[:300]}")
        except Hung:
            self.problems.append(f"{label}: still reading after {HANG_SECONDS} s")
        except Exception as exc:   # noqa: BLE001 (the point of the test: record what escaped)
            self.problems.append(f"{label}: {type(exc).__name__} escaped: {str(exc)[:200]}")
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        seconds = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1] - before
        if outcome:
            self.counts[outcome] += 1
            if os.environ.get("LUMEN_FUZZ_LOG"):          # every case and its outcome, for reading
                with open(os.environ["LUMEN_FUZZ_LOG"], "a") as log:
                    log.write(f"{outcome}\t{label}\t{msg[len(str(self.folder)):][:160]}\n")
        if expect and outcome and outcome != expect:
            self.problems.append(f"{label}: {outcome}, expected {expect}")
        self.slowest = max(self.slowest, (seconds, label))
        self.peak = max(self.peak, (peak, label))
        if seconds > CASE_SECONDS:
            self.problems.append(f"{label}: took {seconds:.1f} s")
        if peak > CASE_PEAK_BYTES:
            self.problems.append(f"{label}: allocated {peak / 2**20:.0f} MiB")

    # helpers for mutations -----------------------------------------------------------------

    def name_of(self, kind: str) -> str:
        """File name of "sdf" or an atlas layer in the original manifest."""
        m = self.manifest
        return m["sdf"]["file"] if kind == "sdf" else m["atlas"]["layers"][kind]["file"]

    def write_manifest(self, folder: Path, m, raw: dict = None, indent=1):
        text = json.dumps(m, indent=indent)
        for token, literal in (raw or {}).items():
            text = text.replace(json.dumps(token), literal)
        (folder / MANIFEST).write_text(text)

    def reseal(self, folder: Path, kind: str, data: bytes, m=None, size=None, sha=None):
        """Put `data` in place of file `kind` under its content name and give the manifest its
        size and SHA-256 (or the given ones), as a crafted cache would."""
        m = copy.deepcopy(self.manifest) if m is None else m
        entry = m["sdf"] if kind == "sdf" else m["atlas"]["layers"][kind]
        (folder / entry["file"]).unlink()
        sha = sha or hashlib.sha256(data).hexdigest()
        stem, ext = ("sdf", "npz") if kind == "sdf" else (f"atlas-{kind.replace('_', '-')}",
                                                           entry["file"].rsplit(".", 1)[1])
        entry.update(file=f"{stem}-{sha[:16]}.{ext}", sha256=sha, size=len(data) if size is None else size)
        (folder / entry["file"]).write_bytes(data)
        self.write_manifest(folder, m)
        return folder / entry["file"]


@pytest.fixture
def fuzzer(original, tmp_path):
    files, manifest, baseline = original
    folder = tmp_path / "cache"
    folder.mkdir()
    return Fuzzer(folder, files, manifest, baseline)


# -- the mutations ------------------------------------------------------------------------------

def walk(node, path=""):
    """(path string, parent, key, value) of every node below the manifest root."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        sub = f"{path}.{key}" if isinstance(node, dict) else f"{path}[{key}]"
        sub = sub.lstrip(".")
        yield sub, node, key, value
        yield from walk(value, sub)


def edits_for(path: str, value, in_dict: bool):
    """(kind, new value or a marker) edits of one manifest node."""
    out = [("missing", None)] if in_dict else [("drop", None)]
    if type(value) in (int, float):
        out += [("nan", float("nan")), ("inf", float("inf")), ("-inf", float("-inf")),
                ("1e999", "RAW:1e999"), ("huge", 1e300), ("-huge", -1e300), ("bigint", 10 ** 18),
                ("longint", "RAW:" + "9" * 30), ("str", str(value)), ("null", None), ("bool", True),
                ("list", [value]), ("dict", {"v": value})]
        if type(value) is int:
            out += [("float", float(value))] + ([] if VALUE_FREE.search(path) else [("frac", value + 0.5)])
        if not SIGN_FREE.search(path):
            out += [("neg", -abs(value) if value else -1), ("zero", type(value)(0))]
    elif type(value) is bool:
        out += [("int1", 1), ("int0", 0), ("str", "true"), ("null", None), ("list", [value])]
    elif type(value) is str:
        out += [("int", 0), ("null", None), ("list", [value]), ("dict", {}), ("empty", ""),
                ("long", "LONG:5000"), ("longer", "LONG:100000"), ("x", "x"), ("upper", value.upper()),
                ("nul", value + "\0"), ("slash", "../" + value)]
    elif type(value) is list:
        out += [("empty", []), ("str", "[]"), ("null", None), ("dict", {}), ("int", 3)]
        if value:
            out += [("append", value + [copy.deepcopy(value[-1])]), ("drop_last", value[:-1])]
    elif type(value) is dict:
        out += [("empty", {}), ("list", []), ("str", "{}"), ("null", None),
                ("extra", {**value, "extra": 1})]
    return out


def manifest_edit_cases(fz: Fuzzer, rng, count=600):
    """`count` edits of (key pattern, edit kind) pairs, each at a random node of its pattern:
    every pattern and every kind at least once, the rest drawn at random."""
    by_pattern = {}
    for path, parent, key, value in walk(fz.manifest):
        pattern = re.sub(r"\[\d+\]", "[*]", path)
        pattern = re.sub(r"(coverage|stats)\.[0-9a-f]{20}", r"\1.*", pattern)
        for kind, new in edits_for(path, value, isinstance(parent, dict)):
            by_pattern.setdefault((pattern, kind), []).append((path, kind, new))
    pairs = list(by_pattern)
    order = rng.permutation(len(pairs))
    picked, patterns, kinds = [], set(), set()
    for i in order:                        # first: a pair for every pattern and every kind
        pattern, kind = pairs[i]
        if pattern not in patterns or kind not in kinds:
            picked.append(i)
            patterns.add(pattern)
            kinds.add(kind)
    rest = [i for i in order if i not in set(picked)]
    picked += rest[:max(count - len(picked), 0)]
    chosen = [by_pattern[pairs[i]][rng.integers(len(by_pattern[pairs[i]]))] for i in picked]
    text = json.dumps(fz.manifest)
    for path, kind, new in chosen:
        def mutate(folder, path=path, kind=kind, new=new):
            m = json.loads(text)
            parent, key = locate(m, path)
            raw = {}
            if kind in ("missing", "drop"):
                del parent[key]
            elif isinstance(new, str) and new.startswith("RAW:"):
                parent[key] = "@@raw@@"
                raw = {"@@raw@@": new[4:]}
            elif isinstance(new, str) and new.startswith("LONG:"):
                parent[key] = "y" * int(new[5:])
            else:
                parent[key] = new
            fz.write_manifest(folder, m, raw, indent=None)
        fz.case(f"manifest {path} {kind}", mutate,
                plausible=kind == "missing" and OPTIONAL.search(path) is not None)
    return len(chosen)


def locate(root, path: str):
    """(parent container, key) of the node at `path` (as walk() spells it)."""
    tokens = re.findall(r"\[(\d+)\]|\.?([^.\[\]]+)", path)
    node = root
    keys = [int(i) if i else name for i, name in tokens]
    for key in keys[:-1]:
        node = node[key]
    return node, keys[-1]


def json_paths_differ(a, b, path=""):
    """Paths where two parsed manifests differ; a structural difference is reported as '!'."""
    if type(a) is not type(b):
        return ["!" + path]
    if isinstance(a, dict):
        if list(a) != list(b):
            return ["!" + path]
        return [p for k in a for p in json_paths_differ(a[k], b[k], f"{path}.{k}".lstrip("."))]
    if isinstance(a, list):
        if len(a) != len(b):
            return ["!" + path]
        return [p for i in range(len(a)) for p in json_paths_differ(a[i], b[i], f"{path}[{i}]")]
    return [] if a == b or (a != a and b != b) else [path]


def manifest_byte_cases(fz: Fuzzer, rng, flips=60, cuts=15):
    text = fz.files[MANIFEST]
    for n in range(flips):
        pos, bit = int(rng.integers(len(text))), int(rng.integers(8))
        data = bytearray(text)
        data[pos] ^= 1 << bit
        data = bytes(data)
        try:
            parsed = json.loads(data)
            diff = json_paths_differ(fz.manifest, parsed)
            plausible = bool(diff) and all(not p.startswith("!") and VALUE_FREE.search(p) for p in diff)
        except (ValueError, RecursionError):
            plausible = False
        fz.case(f"manifest byte {pos} bit {bit}", lambda f, d=data: (f / MANIFEST).write_bytes(d),
                plausible)
    for n in [0, 1, len(text) // 2, len(text) - 1] + list(rng.integers(2, len(text) - 1, cuts)):
        fz.case(f"manifest cut at {n}", lambda f, n=int(n): (f / MANIFEST).write_bytes(text[:n]))
    return flips + 4 + cuts


def manifest_text_cases(fz: Fuzzer):
    m = json.dumps(fz.manifest)
    cases = {
        "a list": b"[]", "a number": b"1", "a string": b'"lumen-gi-cache"', "null": b"null",
        "empty": b"", "deep nesting": b"[" * 100_000 + b"]" * 100_000,
        "deep objects": b'{"a":' * 50_000 + b"1" + b"}" * 50_000,
        "long integer": m.replace('"version": 2', '"version": ' + "2" * 5000).encode(),
        "NaN version": m.replace('"version": 2', '"version": NaN').encode(),
        "bool version": m.replace('"version": 2', '"version": true').encode(),
        "float version": m.replace('"version": 2', '"version": 2.0').encode(),
        "invalid utf-8": m.encode()[:100] + b"\xff\xfe" + m.encode()[100:],
        "utf-8 BOM": b"\xef\xbb\xbf" + m.encode(),
        "utf-16": m.encode("utf-16"),
        "NUL bytes": m.encode() + b"\0" * 10,
        "trailing garbage": m.encode() + b" }",
        "10 MB of spaces": b" " * (10 << 20) + m.encode(),     # valid JSON: reads the same
        "duplicate key, last wins": m.replace('"version": 2', '"version": 99, "version": 2').encode(),
        "lone surrogate": m.replace('"units": "metres"', '"units": "\\ud800"').encode(),
    }
    same = ("10 MB of spaces", "duplicate key, last wins")
    for label, data in cases.items():
        fz.case(f"manifest {label}", lambda f, d=data: (f / MANIFEST).write_bytes(d),
                expect="identical" if label in same else "refused")

    def sparse(folder):
        with open(folder / MANIFEST, "r+b") as fh:
            fh.truncate(MAX_MANIFEST_BYTES + 1)
    fz.case("manifest one byte over the cap (sparse)", sparse, expect="refused")
    return len(cases) + 1


DATA_KINDS = ("sdf", "albedo", "normal", "depth", "emissive", "opacity", "albedo_srgb")


def file_byte_cases(fz: Fuzzer, rng, flips=20, sealed_flips=16, cuts=8):
    """Truncations, appended bytes and byte flips of every data file, plain and resealed."""
    n = 0
    for kind in DATA_KINDS:
        name = fz.name_of(kind)
        data = fz.files[name]
        for cut in [0, 1, len(data) // 2, len(data) - 1] + list(rng.integers(2, len(data) - 1, cuts)):
            cut = int(cut)
            fz.case(f"{name} cut at {cut}", lambda f, c=cut, nm=name, d=data: (f / nm).write_bytes(d[:c]),
                    expect="refused")
            fz.case(f"{name} cut at {cut}, resealed", lambda f, c=cut, k=kind, d=data: fz.reseal(f, k, d[:c]),
                    expect=None if kind == "albedo_srgb" else "refused")
            n += 2
        for extra in (b"\0", os.urandom(1) * 4096, b"PK\x05\x06" + b"\0" * 18):
            fz.case(f"{name} + {len(extra)} bytes",
                    lambda f, nm=name, d=data, e=extra: (f / nm).write_bytes(d + e), expect="refused")
            fz.case(f"{name} + {len(extra)} bytes, resealed",
                    lambda f, k=kind, d=data, e=extra: fz.reseal(f, k, d + e))
            n += 2
        for sealed, count in ((False, flips), (True, sealed_flips)):
            for _ in range(count):
                pos, bit = int(rng.integers(len(data))), int(rng.integers(8))
                flipped = bytearray(data)
                flipped[pos] ^= 1 << bit

                def mutate(f, nm=name, k=kind, d=bytes(flipped), sealed=sealed):
                    if sealed:
                        fz.reseal(f, k, d)
                    else:
                        (f / nm).write_bytes(d)
                fz.case(f"{name} byte {pos} bit {bit}{', resealed' if sealed else ''}", mutate,
                        expect=None if sealed else "refused")
                n += 1
    return n


def special_file_cases(fz: Fuzzer, tmp: Path):
    """Things that are not regular files, missing files, and huge sparse files, in place of each
    file of the cache; none may be opened (a FIFO would block the reader forever)."""
    outside = tmp / "outside"
    outside.mkdir(exist_ok=True)
    n = 0
    for name in [MANIFEST] + [fz.name_of(k) for k in DATA_KINDS]:
        (outside / name).write_bytes(fz.files[name])

        def replace(f, how, nm=name):
            (f / nm).unlink()
            how(f / nm)
        hows = {
            "symlink to /dev/zero": lambda p: p.symlink_to("/dev/zero"),
            "symlink to an identical copy": lambda p, nm=name: p.symlink_to(outside / nm),
            "relative symlink to itself": lambda p: p.symlink_to(p.name),
            "FIFO": lambda p: os.mkfifo(p),
            "directory": lambda p: p.mkdir(),
            "missing": lambda p: None,
            "sparse 5 GiB": lambda p: open(p, "wb").truncate(5 << 30),
            "hard link to an identical copy": lambda p, nm=name: os.link(outside / nm, p),
        }
        if os.path.exists("/dev/null"):
            hows["symlink to /dev/null"] = lambda p: p.symlink_to("/dev/null")
        for label, how in hows.items():
            fz.case(f"{name}: {label}", lambda f, how=how: replace(f, how),
                    expect="identical" if label.startswith("hard link") else "refused")
            n += 1
    # a manifest declaring huge sizes for sparse files of those sizes: refused before reading
    for kind, size in (("sdf", 3 << 30), ("sdf", 5 << 30), ("normal", 3 << 30), ("albedo_srgb", 1 << 40)):
        def mutate(f, kind=kind, size=size):
            path = fz.reseal(f, kind, b"", size=size, sha="0" * 64)
            with open(path, "r+b") as fh:
                fh.truncate(size)
        fz.case(f"{kind} a sparse {size >> 30} GiB file the manifest declares", mutate, expect="refused")
        n += 1
    return n


# crafted .npz files ----------------------------------------------------------------------------

def npz_arrays(fz: Fuzzer) -> dict:
    with zipfile.ZipFile(io.BytesIO(fz.files[fz.name_of("sdf")])) as zf:
        return {i.filename[:-4]: np.lib.format.read_array(zf.open(i), allow_pickle=False)
                for i in zf.infolist()}


def npz_bytes(members, compression=zipfile.ZIP_STORED, comment=b"") -> bytes:
    """A zip of {member name: raw bytes} (names as given, so .npy suffixes are the caller's)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression) as zf:
        for name, raw in members:
            zf.writestr(name, raw)
        zf.comment = comment
    return buf.getvalue()


def npy_bytes(arr=None, header=None, data=b"", version=(1, 0)) -> bytes:
    if header is None:
        out = io.BytesIO()
        np.lib.format.write_array(out, arr, version=version, allow_pickle=arr.dtype.hasobject)
        return out.getvalue()
    h = header.encode("latin1")
    h += b" " * (-(len(h) + 11) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(h)) + h + data


def patch_directory(data: bytes, name: str, **fields) -> bytes:
    """Patch fields of one central-directory entry (flags, method, csize, usize)."""
    data = bytearray(data)
    at = data.find(b"PK\x01\x02")
    while True:
        assert at >= 0, name
        nlen = struct.unpack_from("<H", data, at + 28)[0]
        if data[at + 46:at + 46 + nlen] == name.encode():
            break
        at = data.find(b"PK\x01\x02", at + 4)
    offsets = {"flags": (8, "<H"), "method": (10, "<H"), "csize": (20, "<I"), "usize": (24, "<I")}
    for key, value in fields.items():
        off, fmt = offsets[key]
        struct.pack_into(fmt, data, at + off, value)
    return bytes(data)


def patch_end(data: bytes, **fields) -> bytes:
    data = bytearray(data)
    at = len(data) - 22
    offsets = {"n_disk": (8, "<H"), "n_total": (10, "<H"), "cd_size": (12, "<I"), "cd_offset": (16, "<I")}
    for key, value in fields.items():
        off, fmt = offsets[key]
        struct.pack_into(fmt, data, at + off, value)
    return bytes(data)


def npz_cases(fz: Fuzzer):
    arrays = npz_arrays(fz)
    names = list(arrays)
    members = [(f"{k}.npy", npy_bytes(v)) for k, v in arrays.items()]
    ind = names[0]                     # mesh0_mip0_indirection
    bri = names[1]                     # mesh0_mip0_bricks
    kept = arrays[bri].shape[0]
    zeros = bytes(32 << 20)            # 32 MiB of zeros deflate to ~32 kB
    cases = {}

    def with_member(name, raw, compression=zipfile.ZIP_STORED):
        out = [(n, raw if n == f"{name}.npy" else r) for n, r in members]
        return npz_bytes(out, compression)

    cases["same arrays, members in another order"] = (npz_bytes(members[::-1]), "identical")
    cases["same arrays, zip64 local headers (np.savez)"] = (fz.files[fz.name_of("sdf")], "identical")
    cases["np.savez_compressed"] = (npz_bytes(members, zipfile.ZIP_DEFLATED), "refused")
    cases["bomb: bricks deflated, header says 65536 bricks"] = (with_member(
        bri, npy_bytes(header=f"{{'descr': '|u1', 'fortran_order': False, 'shape': (65536, 8, 8, 8), }}",
                       data=zeros), zipfile.ZIP_DEFLATED), "refused")
    cases["bomb: header declares 2^40 bricks, data short"] = (with_member(
        bri, npy_bytes(header=f"{{'descr': '|u1', 'fortran_order': False, 'shape': ({1 << 40}, 8, 8, 8), }}",
                       data=b"\0" * 4096)), "refused")
    cases["header declares 2^62 int32s"] = (with_member(
        ind, npy_bytes(header=f"{{'descr': '<i4', 'fortran_order': False, 'shape': ({1 << 62},), }}")),
        "refused")
    big_header = b"\x93NUMPY\x02\x00" + struct.pack("<I", 1 << 31) + b"{" * 1000
    cases["npy 2.0 header of 2 GiB"] = (with_member(ind, big_header), "refused")
    cases["npy version 3.0"] = (with_member(ind, npy_bytes(arrays[ind], version=(3, 0))), "refused")
    cases["npy version 2.0, same array"] = (with_member(ind, npy_bytes(arrays[ind], version=(2, 0))),
                                           "identical")
    cases["object array (pickle)"] = (with_member(bri, npy_bytes(np.array([{"x": 1}], dtype=object))),
                                      "refused")
    cases["Fortran order"] = (with_member(ind, npy_bytes(np.asfortranarray(arrays[ind]))),
                              "identical" if arrays[ind].ndim < 2 else "refused")
    cases["big-endian int32"] = (with_member(ind, npy_bytes(arrays[ind].astype(">i4"))), "refused")
    cases["int64 indirection"] = (with_member(ind, npy_bytes(arrays[ind].astype(np.int64))), "refused")
    cases["header with a nested tuple bomb"] = (with_member(
        ind, npy_bytes(header="{'descr': '<i4', 'fortran_order': False, 'shape': "
                       + "(" * 300 + ")" * 300 + "}")),
        "refused")
    cases["header not a dict"] = (with_member(ind, npy_bytes(header="[1, 2, 3]")), "refused")
    cases["extra member"] = (npz_bytes(members + [("extra.npy", npy_bytes(np.zeros(3)))]), "refused")
    cases["missing member"] = (npz_bytes(members[1:]), "refused")
    cases["duplicate member"] = (npz_bytes(members + members[:1]), "refused")
    cases["member outside the folder"] = (npz_bytes([("../" + members[0][0], members[0][1])] + members[1:]),
                                          "refused")
    cases["zip comment"] = (npz_bytes(members, comment=b"hello"), "refused")
    stored = npz_bytes(members)
    cases["directory says bricks are 2 GiB"] = (patch_directory(
        stored, f"{bri}.npy", csize=(1 << 31) - 1, usize=(1 << 31) - 1), "refused")
    cases["directory says bricks inflate to 2 GiB"] = (patch_directory(
        stored, f"{bri}.npy", method=zipfile.ZIP_DEFLATED, usize=(1 << 31) - 1), "refused")
    cases["encrypted flag"] = (patch_directory(stored, f"{bri}.npy", flags=1), "refused")
    cases["end record: 65535 entries (zip64 without records)"] = (patch_end(stored, n_disk=0xFFFF,
                                                                            n_total=0xFFFF), "refused")
    cases["end record: directory of 4 GiB"] = (patch_end(stored, cd_size=0xFFFFFFF0), "refused")
    cases["end record: 1000 entries"] = (patch_end(stored, n_disk=1000, n_total=1000), "refused")
    cases["end record: directory offset past the end"] = (patch_end(stored, cd_offset=len(stored)), "refused")
    bad = arrays[ind].copy()
    bad.flat[np.flatnonzero(bad >= 0)[0] if (bad >= 0).any() else 0] = kept + 5
    cases["indirection points past its bricks"] = (with_member(ind, npy_bytes(bad)), "refused")
    bad = arrays[ind].copy()
    bad.flat[0] = -7
    cases["indirection holds -7"] = (with_member(ind, npy_bytes(bad)), "refused")
    slots = np.flatnonzero(arrays[ind] >= 0)
    if len(slots) >= 2:
        bad = arrays[ind].copy()
        bad.flat[slots[1]] = bad.flat[slots[0]]
        cases["two cells share one brick"] = (with_member(ind, npy_bytes(bad)), "refused")
    cases["bricks of another shape"] = (with_member(bri, npy_bytes(arrays[bri][:, :4])), "refused")
    cases["an image instead of the arrays"] = (fz.files[fz.name_of("normal")], "refused")
    for label, (data, expect) in cases.items():
        fz.case(f"npz: {label}, resealed", lambda f, d=data: fz.reseal(f, "sdf", d), expect=expect)
    # consistent lies: the manifest agrees with a crafted .npz
    def declare_many_bricks(f):
        m = copy.deepcopy(fz.manifest)     # every count in the manifest agrees with the lie
        more = (1 << 22) - kept
        m["meshes"][0]["mips"][0]["bricks_kept"] = 1 << 22
        m["meshes"][0]["stats"][0]["bricks_kept"] += more
        m["meshes"][0]["stats"][0]["bytes"] += more * 512
        m["stats"]["bricks"] += more
        m["stats"]["bytes"] += more * 512
        fz.reseal(f, "sdf", with_member(bri, npy_bytes(
            header=f"{{'descr': '|u1', 'fortran_order': False, 'shape': ({1 << 22}, 8, 8, 8), }}",
            data=zeros), zipfile.ZIP_DEFLATED), m)
    fz.case("npz: manifest and header agree on 2 GiB of bricks, deflated", declare_many_bricks,
            expect="refused")

    def declare_huge_grid(f):
        m = copy.deepcopy(fz.manifest)
        mip = m["meshes"][0]["mips"][0]
        mip["resolution"], mip["brick_grid"] = [7 * 4096] * 3, [4096] * 3
        fz.reseal(f, "sdf", with_member(ind, npy_bytes(
            header="{'descr': '<i4', 'fortran_order': False, 'shape': (4096, 4096, 4096), }")), m)
    fz.case("npz: manifest and header agree on a 4096^3 indirection", declare_huge_grid,
            expect="refused")
    return len(cases) + 2


# crafted images ---------------------------------------------------------------------------------

def image_bytes(data: np.ndarray, ext="exr", fmt="float", compression="zip", tile=None) -> bytes:
    import OpenImageIO as oiio
    fd, path = tempfile.mkstemp(suffix=f".{ext}")
    os.close(fd)
    try:
        spec = oiio.ImageSpec(data.shape[1], data.shape[0], data.shape[2], fmt)
        spec.attribute("compression", compression)
        if tile:
            spec.tile_width = spec.tile_height = tile
        out = oiio.ImageOutput.create(path)
        assert out.open(path, spec) and out.write_image(np.ascontiguousarray(data)), oiio.geterror()
        out.close()
        return Path(path).read_bytes()
    finally:
        os.unlink(path)


def image_cases(fz: Fuzzer):
    base = fz.baseline.atlas.layers
    normal, depth = base["normal"], base["depth"]
    h, w = depth.shape[:2]
    nan = normal.copy()
    nan[1, 2, 0] = np.nan
    inf = depth.copy()
    inf[0, 0, 0] = np.inf
    window = bytearray(fz.files[fz.name_of("depth")])
    at = window.find(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    struct.pack_into("<i", window, at + 12, (1 << 30) - 1)
    cases = {
        ("normal", "same pixels, no compression"): (image_bytes(normal, compression="none"), "identical"),
        ("normal", "same pixels, piz"): (image_bytes(normal, compression="piz"), "identical"),
        ("normal", "the depth layer (1 channel)"): (fz.files[fz.name_of("depth")], "refused"),
        ("depth", "the normal layer (3 channels)"): (fz.files[fz.name_of("normal")], "refused"),
        ("normal", "half floats"): (image_bytes(normal, fmt="half"), "refused"),
        ("normal", "a NaN texel"): (image_bytes(nan), "refused"),
        ("depth", "an infinite texel"): (image_bytes(inf), "refused"),
        ("depth", "one column more"): (image_bytes(np.pad(depth, ((0, 0), (0, 1), (0, 0)))), "refused"),
        ("normal", "RGBA"): (image_bytes(np.pad(normal, ((0, 0), (0, 0), (0, 1)))), "refused"),
        ("normal", "tiled"): (image_bytes(normal, tile=16), "refused"),
        ("normal", "a TIFF"): (image_bytes(normal, ext="tif"), "refused"),
        ("normal", "the sRGB PNG"): (fz.files[fz.name_of("albedo_srgb")], "refused"),
        ("depth", "a data window of 2^30 rows"): (bytes(window), "refused"),
        ("albedo_srgb", "an EXR"): (fz.files[fz.name_of("albedo")], "refused"),
        ("albedo_srgb", "a PNG of another size"): (image_bytes(
            np.zeros((h + 4, w, 3), np.uint8), ext="png", fmt="uint8"), "refused"),
        ("albedo", "the arrays"): (fz.files[fz.name_of("sdf")], "refused"),
    }
    for (kind, label), (data, expect) in cases.items():
        fz.case(f"image {kind}: {label}, resealed", lambda f, k=kind, d=data: fz.reseal(f, k, d),
                expect=expect)
    return len(cases)


def swap_cases(fz: Fuzzer):
    """Files swapped on disk, and names or whole entries swapped in the manifest."""
    pairs = [("albedo", "emissive"), ("depth", "opacity"), ("sdf", "normal"), ("albedo", "albedo_srgb")]
    n = 0
    for a, b in pairs:
        na, nb = fz.name_of(a), fz.name_of(b)

        def files(f, na=na, nb=nb):
            (f / na).write_bytes(fz.files[nb])
            (f / nb).write_bytes(fz.files[na])
        fz.case(f"swap contents of {na} and {nb}", files)

        def entries(f, a=a, b=b):
            m = copy.deepcopy(fz.manifest)
            ea = m["sdf"] if a == "sdf" else m["atlas"]["layers"][a]
            eb = m["atlas"]["layers"][b]
            for key in ("file", "sha256", "size"):
                ea[key], eb[key] = eb[key], ea[key]
            fz.write_manifest(f, m)
        fz.case(f"swap manifest entries of {a} and {b}", entries)

        def names(f, a=a, b=b):
            m = copy.deepcopy(fz.manifest)
            ea = m["sdf"] if a == "sdf" else m["atlas"]["layers"][a]
            eb = m["atlas"]["layers"][b]
            ea["file"], eb["file"] = eb["file"], ea["file"]
            fz.write_manifest(f, m)
        fz.case(f"swap file names of {a} and {b}", names)
        n += 3
    for (i, k), (j, l), field in (((0, 0), (0, 1), "indirection"), ((0, 0), (1, 0), "bricks"),
                                  ((0, 2), (1, 2), "indirection")):
        def arrays(f, i=i, k=k, j=j, l=l, field=field):
            m = copy.deepcopy(fz.manifest)
            x, y = m["meshes"][i]["mips"][k], m["meshes"][j]["mips"][l]
            x[field], y[field] = y[field], x[field]
            fz.write_manifest(f, m)
        fz.case(f"swap array names mesh{i}_mip{k} / mesh{j}_mip{l} {field}", arrays)

    def meshes(f):
        m = copy.deepcopy(fz.manifest)
        m["meshes"].reverse()
        fz.write_manifest(f, m)
    fz.case("swap the two mesh entries", meshes)

    def hashes(f):
        m = copy.deepcopy(fz.manifest)
        a, b = m["meshes"]
        a["hash"], b["hash"] = b["hash"], a["hash"]
        fz.write_manifest(f, m)
    fz.case("swap the two mesh hashes", hashes)

    def mips(f):
        m = copy.deepcopy(fz.manifest)
        m["meshes"][0]["mips"].reverse()
        fz.write_manifest(f, m)
    fz.case("reverse the mips of a mesh", mips)
    return n + 6


# -- the test -----------------------------------------------------------------------------------

@pytest.mark.filterwarnings("ignore:Duplicate name:UserWarning")    # a crafted zip, on purpose
def test_fuzzed_caches_are_refused_or_read_identically(fuzzer, tmp_path, capsys):
    rng = np.random.default_rng(SEED)
    fz = fuzzer
    fz.reset()
    assert difference(fz.baseline, read_cache(fz.folder)) is None      # the unmutated cache reads

    def on_alarm(signum, frame):
        raise Hung()
    previous = signal.signal(signal.SIGALRM, on_alarm)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    tracemalloc.start()
    start = time.perf_counter()
    try:
        made = {
            "manifest values": manifest_edit_cases(fz, rng),
            "manifest bytes": manifest_byte_cases(fz, rng),
            "manifest text": manifest_text_cases(fz),
            "file bytes": file_byte_cases(fz, rng),
            "special files": special_file_cases(fz, tmp_path),
            "crafted npz": npz_cases(fz),
            "crafted images": image_cases(fz),
            "swaps": swap_cases(fz),
        }
    finally:
        tracemalloc.stop()
        signal.signal(signal.SIGALRM, previous)
        signal.setitimer(signal.ITIMER_REAL, 0)
    seconds = time.perf_counter() - start
    rss_growth = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) * 1024
    c = fz.counts
    with capsys.disabled():
        print(f"\ncache fuzz: {sum(made.values())} cases {made}; {c['refused']} refused, "
              f"{c['identical']} read identical, {c['plausible']} plausible edits read; "
              f"{seconds:.1f} s; slowest {fz.slowest[0] * 1e3:.0f} ms ({fz.slowest[1]}); "
              f"largest traced peak {fz.peak[0] / 2**20:.1f} MiB ({fz.peak[1]}); "
              f"peak RSS grew {rss_growth / 2**20:.0f} MiB")
    assert not fz.problems, f"{len(fz.problems)} problems:\n" + "\n".join(fz.problems[:40])
    strict = c["refused"] + c["identical"]
    assert strict >= MIN_CASES, (strict, c)
    assert c["refused"] >= 0.8 * strict            # most mutations must be refused, not shrugged off
    assert rss_growth < RSS_GROWTH_BYTES, f"peak RSS grew {rss_growth / 2**20:.0f} MiB"
