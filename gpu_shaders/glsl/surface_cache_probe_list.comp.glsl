#include "surface_cache_pages_lib.glsl"
#include "surface_cache_probe_lib.glsl"
/* Surface cache indirect light, the rays to trace this frame: one invocation per probe of this
 * frame's tiles (as surface_cache_probe_place). A probe with a site appends the rows of its 4x4
 * ray block it traces this frame (all 4, or with the ray LOD 2 or 1 of them) to ray_rows
 * (RGBA32F: probe x, y, row; index from the atomic counter row_counter, cleared before); the
 * texels it does not trace are written a = 0 here (surface_cache_probe_sh leaves them out), as
 * are a probe without a site's. surface_cache_probe_trace then runs 4 invocations per listed row,
 * and none for the rest.
 * Why: on llvmpipe an invocation of a large shader that returns at once costs nearly what one
 * that traces does (measured: screen_probe_list.comp.glsl): the tiles'
 * probes without a site (texels no card covers) and the rows the LOD skips cost the trace as
 * much as traced rays.
 * Ray LOD (lecture: the surface cache's resolution follows the card's size on screen): a probe
 * whose 4x4 texels span few pixels traces only rows of its ray block, 2 of 4 or 1 of 4 (stride
 * 2 or 4, the row frame % stride: every row in turn over the updates), so that it still traces
 * at least lod_rays rays per pixel it covers (probe side in pixels: 4 texels' world size x
 * lod_focal / distance to cam_pos; lod_focal = 0: every ray). Fewer rays, the same expectation.
 * Inputs: texel_card, card tables, sc_pages, sc_tile_frame, sc_probes, sc_probe_pos; frame,
 * cam_pos, lod_focal, lod_rays. Images: ray_rows, row_counter (R32I), out_image (the rays).
 */
void main()
{
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 probe = scp_page_tile(gid.x / SCP_TILE) * SCP_TILE + ivec2(gid.x % SCP_TILE, gid.y);
  ivec2 size = imageSize(out_image) / SCP_SIZE;
  if (probe.x >= size.x || probe.y >= size.y) {
    return;
  }
  vec4 site = texelFetch(sc_probes, probe, 0);
  int stride = 1;
  if (site.w >= 0.5 && lod_focal > 0.0) {
    int row = int(site.w + 0.5) - 1;
    int obj = int(sc_card(row, 0).x + 0.5);
    vec4 t1 = sc_card(row, 1);
    vec4 t2 = sc_card(row, 2);
    vec2 local_texel = (t2.zw - t2.xy) / max(t1.zw, vec2(1.0));
    float scale = pow(abs(determinant(mat3(sc_object_w2l(obj)))), -1.0 / 3.0);
    float side = float(SCP_SIZE) * max(local_texel.x, local_texel.y) * scale * lod_focal
                 / max(distance(texelFetch(sc_probe_pos, probe, 0).xyz, cam_pos), 1e-3);
    float covered = side * side;       /* the probe's side in pixels, squared */
    stride = float(SCP_RAYS / 4) >= lod_rays * covered ? 4
             : (float(SCP_RAYS / 2) >= lod_rays * covered ? 2 : 1);
  }
  ivec2 lsize = imageSize(ray_rows);
  for (int y = 0; y < SCP_SIZE; y++) {
    if (site.w >= 0.5 && y % stride == frame % stride) {
      int e = imageAtomicAdd(row_counter, ivec2(0, 0), 1);
      imageStore(ray_rows, ivec2(e % lsize.x, e / lsize.x), vec4(vec2(probe), float(y), 0.0));
      continue;
    }
    for (int x = 0; x < SCP_SIZE; x++) {
      imageStore(out_image, probe * SCP_SIZE + ivec2(x, y), vec4(0.0));
    }
  }
}
