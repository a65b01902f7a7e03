"""compute.Pass: a pass binds every input from its declaration (missing or unknown inputs raise),
a shared declaration with anything after its ';' is refused (compute.hoist_shared),
push constants over Vulkan's 128 bytes go through a uniform block and still read right, and every
Pass the engine declares compiles (the runner fails any run that prints Blender's push-constant
warning). llvmpipe, bpy in a subprocess."""
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
import mathutils
from lumen_gi.gpu_shaders import compute

OUT = {}
BIG = '''
#include "sampling_lib.glsl"
void main()
{
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= imageSize(out_image).x || p.y >= imageSize(out_image).y) {
    return;
  }
  vec4 v = vec4(0.0);
  if (p.x == 0) { v = t_mat[p.y]; }                     /* the matrix's columns */
  if (p.x == 1) { v = vec4(t_v3, t_f); }
  if (p.x == 2) { v = vec4(t_v2, float(t_i), float(t_iv2.x)); }
  if (p.x == 3) { v = t_v4a; }
  if (p.x == 4) { v = t_v4b; }
  if (p.x == 5) { v = vec4(texelFetch(src, ivec2(0), 0).x, float(pcg_hash(7u) > 0u), t_f2, float(t_iv2.y)); }
  imageStore(out_image, p, v);
}
'''
SMALL = '''
void main()
{
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  vec4 v = vec4(0.0);
  if (p.x == 1) { v = vec4(t_v3, t_f); }
  if (p.x == 2) { v = vec4(t_v2, texelFetch(src, ivec2(0), 0).x, 0.0); }
  imageStore(out_image, p, v);
}
'''
PUSH = (('MAT4', 't_mat'), ('VEC3', 't_v3'), ('FLOAT', 't_f'), ('VEC2', 't_v2'), ('INT', 't_i'),
        ('IVEC2', 't_iv2'), ('VEC4', 't_v4a'), ('VEC4', 't_v4b'), ('FLOAT', 't_f2'))

def job():
    big = compute.Pass("test_big_push", samplers=("src",), push=PUSH, source=BIG)
    OUT["big_bytes"] = compute.push_bytes(PUSH)
    OUT["big_block"] = big.block
    src = compute.texture((1, 1), 'R32F')
    src.clear(format='FLOAT', value=(0.25,))
    out = compute.texture((6, 4))
    M = mathutils.Matrix(((1, 2, 3, 4), (5, 6, 7, 8), (9, 10, 11, 12), (13, 14, 15, 16)))
    inputs = dict(src=src, out_image=out, t_mat=M, t_v3=(0.5, -1.5, 2.5), t_f=3.25, t_v2=(7.0, -8.0),
                  t_i=-9, t_iv2=(10, 2 ** 20), t_v4a=(1.0, 2.0, 3.0, 4.0),
                  t_v4b=(5.0, 6.0, 7.0, 8.0), t_f2=-0.125)
    big.run((6, 4), **inputs)
    OUT["big"] = compute.read(out).tolist()
    small = compute.Pass("test_small_push", samplers=("src",), push=PUSH[1:4], source=SMALL)
    OUT["small_block"] = small.block
    small.run((6, 4), src=src, out_image=out, t_v3=(0.5, -1.5, 2.5), t_f=3.25, t_v2=(7.0, -8.0))
    OUT["small"] = compute.read(out).tolist()
    errors = []
    for bad in ({k: v for k, v in inputs.items() if k != "t_iv2"}, dict(inputs, extra=1.0),
                {k: v for k, v in inputs.items() if k != "src"}):
        try:
            big.run((6, 4), **bad)
            errors.append(None)
        except ValueError as e:
            errors.append(str(e))
    OUT["errors"] = errors
    # a shared declaration hoist_shared cannot move (something after its ';') is refused on every
    # Blender (5.3 alone dropped it when left in place)
    noted = compute.Pass("test_shared_noted", source='''
shared float s_a[64];    /* a note */
void main()
{
  s_a[0] = 1.0;
  imageStore(out_image, ivec2(0), vec4(s_a[0]));
}
''')
    try:
        noted.shader
        OUT["shared_noted"] = None
    except ValueError as e:
        OUT["shared_noted"] = str(e)
    # every Pass the engine's modules declare compiles, within 128 B or through a block
    passes = {}
    for p in compute.declared_passes():
        for defines in p.variant_sets():       # compute.VARIANTS: with cut-outs and without
            p.shader_of(defines)
        passes[p.name] = dict(bytes=compute.push_bytes(p.push), block=p.block,
                              variants=len(p.variant_sets()))
    OUT["passes"] = passes

run_in_gpu_context(job)
emit(**OUT)
"""


def test_pass_binds_from_its_declaration(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    out = run.result
    assert out["big_bytes"] > 128 and out["big_block"]
    big = out["big"]                       # [y][x][rgba]
    M = [[1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 12], [13, 14, 15, 16]]
    for col in range(4):                   # GLSL m[col] is column col of M
        assert big[col][0] == [M[r][col] for r in range(4)]
    assert big[0][1] == [0.5, -1.5, 2.5, 3.25]
    assert big[0][2] == [7.0, -8.0, -9.0, 10.0]
    assert big[0][3] == [1.0, 2.0, 3.0, 4.0] and big[0][4] == [5.0, 6.0, 7.0, 8.0]
    assert big[0][5] == [0.25, 1.0, -0.125, 2.0 ** 20]
    assert not out["small_block"]
    assert out["small"][0][1] == [0.5, -1.5, 2.5, 3.25]
    assert out["small"][0][2] == [7.0, -8.0, 0.25, 0.0]
    missing, unknown, sampler = out["errors"]
    assert missing == "pass test_big_push: missing input 't_iv2'"
    assert unknown == "pass test_big_push: unknown input 'extra'"
    assert sampler == "pass test_big_push: missing input 'src'"
    assert "alone on its line" in out["shared_noted"] and "s_a[64]" in out["shared_noted"]
    assert out["passes"], "no compute.Pass found in the engine's modules"
    for name, p in out["passes"].items():
        assert p["bytes"] <= 128 or p["block"], name
    # the passes that trace shadows or GI rays compile a cut-out variant too (compute.VARIANTS)
    for name in ("direct_light", "surface_cache_direct", "screen_probe_trace"):
        assert out["passes"][name]["variants"] == 2, (name, out["passes"][name])
