"""gpu_shaders/glsl_include.py: `#include "x.glsl"` resolved in dependency order, each file once."""
import pytest

from gpu_shaders import glsl_include


def write(folder, files):
    for name, text in files.items():
        (folder / name).write_text(text)


def test_dependencies_first_each_once(tmp_path):
    write(tmp_path, {
        "a_lib.glsl": "int a() { return 1; }\n",
        "b_lib.glsl": '#include "a_lib.glsl"\nint b() { return a(); }\n',
        "c_lib.glsl": '  #include "a_lib.glsl"\nint c() { return a(); }\n',
        "p.comp.glsl": '#include "c_lib.glsl"\n#include "b_lib.glsl"\nvoid main() {}\n',
    })
    assert glsl_include.files("p.comp.glsl", tmp_path) == [
        "a_lib.glsl", "c_lib.glsl", "b_lib.glsl", "p.comp.glsl"]
    src = glsl_include.source("p.comp.glsl", tmp_path)
    assert src.count("int a()") == 1 and "#include" not in src
    assert src.index("int a()") < src.index("int c()") < src.index("int b()") < src.index("main")
    # several roots share their libraries
    assert glsl_include.files(("b_lib.glsl", "c_lib.glsl"), tmp_path) == [
        "a_lib.glsl", "b_lib.glsl", "c_lib.glsl"]


def test_missing_file_names_the_includer(tmp_path):
    write(tmp_path, {"p.comp.glsl": '#include "b_lib.glsl"\n',
                     "b_lib.glsl": '#include "gone_lib.glsl"\n'})
    with pytest.raises(FileNotFoundError, match=r"b_lib\.glsl.*gone_lib\.glsl"):
        glsl_include.source("p.comp.glsl", tmp_path)


def test_cycle_raises(tmp_path):
    write(tmp_path, {"p.comp.glsl": '#include "a_lib.glsl"\n',
                     "a_lib.glsl": '#include "b_lib.glsl"\n',
                     "b_lib.glsl": '#include "a_lib.glsl"\n'})
    with pytest.raises(ValueError, match="a_lib.glsl -> b_lib.glsl -> a_lib.glsl"):
        glsl_include.files("p.comp.glsl", tmp_path)


def test_every_shader_source_resolves():
    """Every GLSL file resolves (no missing file, no cycle), each file once, itself last; the
    tracers' libraries come in the order they need."""
    names = sorted(p.name for p in glsl_include.GLSL.glob("*.glsl"))
    assert any(n.endswith(".comp.glsl") for n in names)
    for name in names:
        order = glsl_include.files(name)
        assert order[-1] == name and len(order) == len(set(order))
        src = glsl_include.source(name)
        assert "#include" not in src
        if name.endswith(".comp.glsl"):
            assert src.count("void main()") == 1, name
    # the tracers need the whole stack, in order (the screen trace's pass: all of it)
    order = glsl_include.files("screen_probe_screen_trace.comp.glsl")
    for before, after in (("sdf_lib.glsl", "sdf_ray_lib.glsl"), ("sdf_ray_lib.glsl", "gi_trace_lib.glsl"),
                          ("global_sdf_lib.glsl", "voxel_lighting_lib.glsl"),
                          ("voxel_lighting_trace_lib.glsl", "gi_trace_lib.glsl"),
                          ("gi_trace_lib.glsl", "lumen_trace_lib.glsl"),
                          ("screen_trace_lib.glsl", "lumen_trace_lib.glsl")):
        assert order.index(before) < order.index(after)
    # the default probe trace holds no screen-trace code (llvmpipe pays for code it never runs)
    plain = glsl_include.files("screen_probe_trace.comp.glsl")
    assert "gi_trace_lib.glsl" in plain
    assert "screen_trace_lib.glsl" not in plain and "lumen_trace_lib.glsl" not in plain
