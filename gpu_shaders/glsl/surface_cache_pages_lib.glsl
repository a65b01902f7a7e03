/* Lumen GI: the surface-cache passes run over this frame's tiles only (surface_cache_pages.py):
 * sc_pages holds one texel per tile (tile x, tile y, temporal blend); a pass dispatches
 * (tiles x 32) x 32 threads for texels, (tiles x 8) x 8 for probes, and thread x / (tile width)
 * picks the tile. */
#define SCP_TILE 8               /* probes per tile side */
#define SCP_PAGE_TEXELS 32       /* lighting texels per tile side */

ivec2 scp_page_tile(int page)
{
  return ivec2(texelFetch(sc_pages, ivec2(page, 0), 0).xy + 0.5);
}

float scp_page_blend(int page)
{
  return texelFetch(sc_pages, ivec2(page, 0), 0).z;
}

/* The lighting texel (or ray texel) of thread gid of a texel-sized dispatch. */
ivec2 scp_page_texel(ivec2 gid)
{
  return scp_page_tile(gid.x / SCP_PAGE_TEXELS) * SCP_PAGE_TEXELS
         + ivec2(gid.x % SCP_PAGE_TEXELS, gid.y);
}
