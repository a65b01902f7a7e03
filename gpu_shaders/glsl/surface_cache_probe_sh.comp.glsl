#include "sdf_ray_lib.glsl"
#include "sh_lib.glsl"
#include "surface_cache_pages_lib.glsl"
#include "surface_cache_probe_lib.glsl"
/* Surface cache indirect light, step 2: spatial filter + two-band SH (lecture: "Spatial filtering
 * between probes, convert to TwoBandSH"). Per probe, the rays of the 3x3 neighbouring probes on
 * the same card whose normals agree (cos > 0.9) and that no wall hides (gi_visible: the two sides of
 * a thin wall on one floor card must not mix) are projected together:
 *   c_k = sum_rays L Y_k(dir) 2 pi / (rays used)
 * (uniform hemisphere rays: each ray stands for 2 pi / 16 sr of its probe; the other hemisphere
 * is empty; a slot the trace's ray LOD skipped, a = 0, is no ray).
 * Also the irradiance at the probe's own normal from the same rays, E0 = sum L max(0, n.dir)
 * 2 pi / (rays used): exact where two-band SH is not (a small bright source near the
 * normal reads 25% low through SH4's clamped-cosine convolution); the texels use E0 and take from
 * the SH only how their normal differs from the probe's.
 * Runs over this frame's tiles (sc_pages); a neighbour in another tile keeps the rays of that
 * tile's last update, traced with that frame's jitter (sc_tile_frame).
 * Inputs: sc_rays, sc_probes, sc_probe_pos (trace outputs), sc_probe_room (probe_place: the
 * field at each probe's lifted end), sc_pages, sc_tile_frame.
 * Output out_image: SH coefficient k of probe (i, j) at texel (2 i + k % 2, 2 j + k / 2), rgb;
 * irradiance_out: E0 of probe (i, j).
 */
void main()
{
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 probe = scp_page_tile(gid.x / SCP_TILE) * SCP_TILE + ivec2(gid.x % SCP_TILE, gid.y);
  ivec2 grid = textureSize(sc_probes, 0);
  if (probe.x >= grid.x || probe.y >= grid.y) {
    return;
  }
  vec4 own = texelFetch(sc_probes, probe, 0);
  vec3 c[4] = vec3[4](vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
  vec3 e0 = vec3(0.0);
  if (own.w > 0.5) {
    float rays = 0.0;
    vec4 a = texelFetch(sc_probe_pos, probe, 0);
    vec3 lifted = gi_lifted(a.xyz, own.xyz, a.w);
    float room = texelFetch(sc_probe_room, probe, 0).x;   /* the field there (probe_place) */
    vec4 ga = vec4(0.0);         /* its gradient, for the tests that need it */
    for (int dy = -1; dy <= 1; dy++) {
      for (int dx = -1; dx <= 1; dx++) {
        ivec2 q = probe + ivec2(dx, dy);
        if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, grid))) {
          continue;
        }
        vec4 qi = texelFetch(sc_probes, q, 0);
        if (abs(qi.w - own.w) > 0.5 || dot(qi.xyz, own.xyz) < 0.9) {
          continue;
        }
        if (q != probe) {
          vec4 b = texelFetch(sc_probe_pos, q, 0);
          if (!gi_visible_between(lifted, room, gi_lifted(b.xyz, qi.xyz, a.w),
                                  texelFetch(sc_probe_room, q, 0).x, a.w, ga)) {
            continue;
          }
        }
        int q_frame = scp_probe_frame(q);
        for (int k = 0; k < SCP_RAYS; k++) {
          vec4 ray = texelFetch(sc_rays, q * SCP_SIZE + ivec2(k & 3, k >> 2), 0);
          if (ray.a <= 0.0) {
            continue;                  /* a slot the ray LOD skipped (a = 0) */
          }
          vec3 L = ray.rgb;
          rays += 1.0;
          float b[4];
          vec3 dir = scp_dir(q, q_frame, k, qi.xyz);
          sh4_basis(dir, b);
          e0 += L * max(dot(dir, own.xyz), 0.0);
          for (int i = 0; i < 4; i++) {
            c[i] += L * b[i];
          }
        }
      }
    }
    float w = 6.28318530717958648 / max(rays, 1.0);
    for (int i = 0; i < 4; i++) {
      c[i] *= w;
    }
    e0 *= w;
  }
  imageStore(irradiance_out, probe, vec4(e0, 1.0));
  for (int i = 0; i < 4; i++) {
    imageStore(out_image, probe * 2 + ivec2(i & 1, i >> 1), vec4(c[i], 1.0));
  }
}
