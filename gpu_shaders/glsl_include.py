"""`#include "x.glsl"` for the engine's GLSL (no gpu, no bpy: tests/core runs it).

Why: GLSL compilers reject `#include` without an extension, and the libraries must come before
what uses them. Each file names the libraries it uses at its top; `source(name)` returns the
file with every library it needs, recursively, each once, in dependency order (depth first, in
the order the lines name them), the `#include` lines removed. So a file's own `#define`s come
after its libraries and cannot configure them (a debug switch put at a shader's top is not seen
by the library code it is meant for).
"""
from __future__ import annotations

import re
from pathlib import Path

GLSL = Path(__file__).resolve().parent / "glsl"
INCLUDE = re.compile(r'^[ \t]*#include[ \t]+"([^"]+)"[ \t]*$', re.M)


def includes(text: str) -> list:
    """The file names a source's `#include` lines name, in order."""
    return INCLUDE.findall(text)


def files(names, folder: Path = GLSL) -> list:
    """`names` (one file name or several) and every file they include, recursively, each once,
    a file after all it includes. Raises FileNotFoundError naming the including file for a
    missing one, ValueError on a cycle."""
    order, done = [], set()

    def visit(f, chain):
        if f in done:
            return
        if f in chain:
            raise ValueError("GLSL include cycle: " + " -> ".join(chain[chain.index(f):] + [f]))
        path = Path(folder) / f
        if not path.is_file():
            raise FileNotFoundError(f"{chain[-1] if chain else f}: included file {f!r} not found"
                                    f" in {folder}")
        for lib in includes(path.read_text(encoding="utf-8")):
            visit(lib, chain + [f])
        done.add(f)
        order.append(f)

    for name in ((names,) if isinstance(names, str) else names):
        visit(name, [])
    return order


def source(names, folder: Path = GLSL) -> str:
    """The text of `names` (one file name or several) after the files they include
    (recursively, each once), `#include` lines removed."""
    return "\n".join(INCLUDE.sub("", (Path(folder) / f).read_text(encoding="utf-8"))
                     for f in files(names, folder))
