"""Every module-level shader cache of the engine is freed before Blender's GPU module goes
(gpu_shaders.free_shaders): a compiled shader freed by Python's last garbage collection, after
the textures it was bound to, crashed Blender at exit. Read from the sources (no gpu import)."""
import ast
import re
from pathlib import Path

GPU = Path(__file__).resolve().parents[2] / "gpu_shaders"


def listed_caches():
    tree = ast.parse((GPU / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and node.targets[0].id == "_SHADER_CACHES":
            return set(ast.literal_eval(node.value))
    raise AssertionError("gpu_shaders/__init__.py has no _SHADER_CACHES")


def test_every_shader_cache_is_freed():
    found = set()
    for f in sorted(GPU.glob("*.py")):
        for m in re.finditer(r"^(_SHADERS?) = \{\}", f.read_text(encoding="utf-8"), re.M):
            found.add((f.stem, m.group(1)))
    assert found, "no shader cache found: the pattern is stale"
    assert found == listed_caches(), (
        f"caches not freed: {sorted(found - listed_caches())}; "
        f"listed but absent: {sorted(listed_caches() - found)}")
