#include "radiance_cache_layout_lib.glsl"
/* Lumen GI: marking radiance-cache cells as used (needs radiance_cache_layout_lib.glsl and the
 * R32F image rc_marks): the passes whose rays hand over to the cache (screen_probe_trace,
 * screen_probe_integrate's fallback rays) mark the 8 cells around the rays' origin, so that
 * radiance_cache_alloc gives them probes. */
void rc_mark(vec3 p, int k, int frame)
{
  ivec3 i0 = ivec3(floor(p / rc_spacing(k) - 0.5));
  for (int c = 0; c < 8; c++) {
    ivec3 cell = i0 + ivec3(c & 1, (c >> 1) & 1, c >> 2);
    imageStore(rc_marks, rc_cell_texel(k, cell), vec4(float(frame + 1)));
  }
}
