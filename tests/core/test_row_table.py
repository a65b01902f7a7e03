"""packing.row_table: rows of K texels, 1,024 rows a texture line (glsl/row_table_lib.glsl reads
row r's texel t at ((r % 1024) K + t, r // 1024)); the last line padded."""
import re
from pathlib import Path

import numpy as np

from gpu_shaders import packing

GLSL = Path(__file__).resolve().parents[2] / "gpu_shaders" / "glsl" / "row_table_lib.glsl"


def row_texel(row, t, k, line=packing.ROWS_PER_LINE):
    """The GLSL function's arithmetic."""
    return (row % line) * k + t, row // line


def test_row_table_places_every_row_where_the_glsl_reads_it():
    assert re.search(r"#define ROW_TABLE_LINE (\d+)", GLSL.read_text()).group(1) == \
        str(packing.ROWS_PER_LINE)
    rng = np.random.default_rng(1)
    for n, k in ((1, 10), (7, 4), (1024, 6), (1025, 1), (3000, 10)):
        rows = rng.normal(size=(n, k, 4)).astype(np.float32)
        pad = np.full((k, 4), 9.0, np.float32)
        table = packing.row_table(rows, pad)
        assert table.shape[1] == min(n, 1024) * k and table.shape[1] <= 16384
        for r in {0, n // 2, n - 1}:
            for t in range(k):
                x, y = row_texel(r, t, k)
                np.testing.assert_array_equal(table[y, x], rows[r, t])
        # the rows a table holds (row_table_rows): every one past n is the pad
        held = (table.shape[1] // k) * table.shape[0]
        assert n <= held < n + 1024
        for r in range(n, held):
            x, y = row_texel(r, 0, k)
            np.testing.assert_array_equal(table[y, x:x + k], pad)
