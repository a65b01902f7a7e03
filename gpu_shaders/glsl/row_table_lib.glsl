/* Lumen GI: row tables (packing.row_table): rows of k texels, 1,024 rows a texture line, so a
 * table of many rows (object, card and instance tables) never outgrows the GPU's largest
 * texture side. Row r's texel t. */
#ifndef LUMEN_ROW_TABLE_LIB
#define LUMEN_ROW_TABLE_LIB

#define ROW_TABLE_LINE 1024   /* packing.ROWS_PER_LINE */

ivec2 row_texel(int row, int t, int k)
{
  return ivec2((row % ROW_TABLE_LINE) * k + t, row / ROW_TABLE_LINE);
}

/* The rows a table of k-texel rows holds (those of its last line past the data included). */
int row_table_rows(ivec2 size, int k)
{
  return (size.x / k) * size.y;
}

#endif /* LUMEN_ROW_TABLE_LIB */
