#include "probe_interp_lib.glsl"
/* Screen probes, adaptive placement (lecture: "Screen Probe Placement: adaptive placement with
 * hierarchical refinement, iteratively place where interpolation fails" and "Screen Probe Atlas:
 * adaptive probes at the bottom of the atlas"). Per tile of 8x8 pixels (level 1), then 4x4
 * (level 2): its jittered pixel (the uniform probes' jitter, scaled) gets a probe when the 4
 * uniform probes around it do not interpolate it (probe_corner_weights: plane distance x
 * bilinear, lighting_valid 0) and, at level 2, the level-1 probe of its 8x8 tile (if placed)
 * is not on its plane either. Level 1 is re-derived at level 2 (the same test on the parent's
 * pixel), so one dispatch places both without reading what it writes.
 * Atlas (probe_info / probe_normal, ScreenProbes.adaptive): uniform probes at [0, gw) x [0, gh),
 * level 1 at [0, 2 gw) x [gh, 3 gh), level 2 at [0, 4 gw) x [3 gh, 7 gh); a slot without a
 * probe keeps w = 0. This pass writes the whole atlas: the uniform block copied from
 * screen_probe_place's textures, the rest placed here.
 * Inputs: gbuf_position, gbuf_normal, probe_uniform, probe_uniform_normal (screen_probe_place's
 * outputs); cam_pos, probe_tile, tile_jitter, uniform_rows (gh).
 * Outputs: out_image (probe_info), probe_normal_out, as screen_probe_place's.
 */
bool adaptive_pixel(ivec2 px, out vec3 p, out vec3 n)
{
  ivec2 size = textureSize(gbuf_position, 0);
  px = min(px, size - 1);
  vec4 pos = texelFetch(gbuf_position, px, 0);
  if (pos.w < 0.5) {
    return false;
  }
  p = pos.xyz;
  n = normalize(texelFetch(gbuf_normal, px, 0).xyz);
  if (dot(n, cam_pos - p) < 0.0) {
    n = -n;
  }
  return true;
}

/* true when the uniform probes do not interpolate pixel px (p, n: its surface) */
bool adaptive_needed(ivec2 px, vec3 p, vec3 n)
{
  ivec2 grid = textureSize(probe_uniform, 0);
  vec2 g = (vec2(px) + 0.5) / float(probe_tile) - 0.5;
  ivec2 i0 = ivec2(floor(g));
  vec2 f = g - vec2(i0);
  vec4 info[4];
  vec4 valid;
  ivec2 q[4] = ivec2[4](i0, i0 + ivec2(1, 0), i0 + ivec2(0, 1), i0 + ivec2(1, 1));
  for (int k = 0; k < 4; k++) {
    info[k] = texelFetch(probe_uniform, clamp(q[k], ivec2(0), grid - 1), 0);
    valid[k] = info[k].w > 0.0 ? 1.0 : 0.0;
  }
  float ok;
  probe_corner_weights(f, info[0].xyz, info[1].xyz, info[2].xyz, info[3].xyz, valid,
                       vec4(n, dot(n, p)), max(distance(p, cam_pos), 1e-4), ok);
  return ok < 0.5;
}

void main()
{
  ivec2 slot = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  int gh = uniform_rows;
  int gw = size.x / 4;
  int y = slot.y;
  if (slot.x >= size.x || y >= size.y) {
    return;
  }
  if (y < gh) {
    bool u = slot.x < gw;
    imageStore(out_image, slot, u ? texelFetch(probe_uniform, slot, 0) : vec4(0.0));
    imageStore(probe_normal_out, slot,
               u ? texelFetch(probe_uniform_normal, slot, 0) : vec4(0.0, 0.0, 1.0, -1.0));
    return;
  }
  int level = y < 3 * gh ? 1 : 2;
  ivec2 tile = ivec2(slot.x, y - (level == 1 ? gh : 3 * gh));
  int T = probe_tile >> level;
  ivec2 jit = ivec2(tile_jitter) * T / probe_tile;
  ivec2 px = tile * T + jit;
  ivec2 store = ivec2(slot.x, y);
  bool inside = tile.x < (level == 1 ? 2 * gw : 4 * gw);
  vec3 p, n;
  bool place = inside && adaptive_pixel(px, p, n) && adaptive_needed(px, p, n);
  if (place && level == 2) {        /* covered by its 8x8 tile's probe? */
    int T1 = probe_tile >> 1;
    ivec2 px1 = (tile / 2) * T1 + ivec2(tile_jitter) * T1 / probe_tile;
    vec3 p1, n1;
    if (adaptive_pixel(px1, p1, n1) && adaptive_needed(px1, p1, n1)) {
      float rel = abs(dot(vec4(p1, -1.0), vec4(n, dot(n, p)))) / max(distance(p, cam_pos), 1e-4);
      place = exp2(-PROBE_PLANE_SHARPNESS * rel * rel) <= 0.1;
    }
  }
  if (!place) {
    imageStore(out_image, store, vec4(0.0));
    imageStore(probe_normal_out, store, vec4(0.0, 0.0, 1.0, -1.0));
    return;
  }
  ivec2 gsize = textureSize(gbuf_position, 0);
  px = min(px, gsize - 1);
  imageStore(out_image, store, vec4(p, max(distance(p, cam_pos), 1e-4)));
  imageStore(probe_normal_out, store, vec4(n, float(px.x + px.y * gsize.x)));
}
