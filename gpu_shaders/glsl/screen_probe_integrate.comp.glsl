#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "surface_cache_lib.glsl"
#include "gbuffer_lib.glsl"
#include "gbuffer_shading_lib.glsl"
#include "sh_lib.glsl"
#include "probe_interp_lib.glsl"
#include "probe_occlusion_lib.glsl"
#include "sampling_lib.glsl"
/* Screen probes, per-pixel integration (lecture: "Final integration with SH" and "Plane distance
 * weighting of Probe Interpolation"): the 4 probes around the pixel (tile centres as the bilinear
 * grid), weighted by probe_corner_weights (bilinear x plane distance), probes that a wall hides
 * from the pixel (their occlusion maps: probe_occ_visible) left out; irradiance
 * E = sum w_i sh9_irradiance(c_i, n). Where the plane weights fail (lighting_valid 0) the visible
 * probes are used by their bilinear weights alone, and with none visible the pixel needs rays of
 * its own: it writes (sc_near_emission, w = 0) and appends
 * (px, voxel) to the list fb_list (slot from the atomic counter fb_counter, cleared each frame);
 * screen_probe_fallback traces those pixels' rays and adds their irradiance. Why a list: traced
 * here, every work group waited on its slowest pixel (with 1,000 small objects most groups held
 * one or two such pixels), while the list packs them into full groups.
 * Inputs: gbuf_position, gbuf_normal, probe_info, probe_normal, probe_sh, probe_occ
 * (screen_probe_occlusion), the mesh SDFs (the pixel's object) and the surface cache (near
 * emission); cam_pos, probe_tile; images fb_list (RGBA32F, at least the
 * dispatch's pixel count) and fb_counter (R32I 1x1).
 * With adaptive probes (uniform_rows > 0: screen_probe_adaptive's atlas, the uniform block
 * [0, gw) x [0, uniform_rows)) a pixel the uniform probes do not interpolate first takes the
 * adaptive probes of its 2x2 nearest 8x8 and 4x4 tiles that lie on its plane (w = 0.5).
 * Every E adds sc_near_emission (surface_cache_lib.glsl): emitters nearer the pixel's surface than
 * any probe ray starts (an emissive panel under a ceiling lights the ceiling around it).
 * Output out_image: E.rgb (irradiance, W/m^2), w = 1 interpolated, 0.5 adaptive, 0 fallback
 * (the visible uniform probes' bilinear weights or screen_probe_fallback's rays), -1 background.
 * The viewport integrates one pixel of every px_step x px_step block per redraw (px_phase: which;
 * the dispatch covers the image / px_step): screen_probe_temporal_split fills the others.
 */
/* A probe lights a pixel only if its normal is within ~60 degrees of the pixel's: its SH holds
 * the radiance around its own surface (the rays below it start inside that surface's shell), so
 * read at a normal turned far from its own it extrapolates. The plane test alone let the floor's
 * probes by an open box's front edge light the edge's outward face, which Cycles shows black
 * (bench/ssim_map.py: cornell's dark class). Such pixels take probes that face their way, else
 * their own rays. */
#define PROBE_NORMAL_MIN 0.5

/* Whether uniform probe q (position b, normal nb) may light the pixel whose lifted end is pa
 * (its object's voxel `voxel`), from the probe's occlusion map (probe_occlusion_lib.glsl): pa
 * must lie on the probe's lifted plane (within a quarter of its distance, plus the hit shell),
 * within the map's reach, and no nearer than the free distance of both azimuths either side of
 * its direction. A wall between the probe and the pixel crosses one of them unless it ends
 * inside that wedge (a doorway's jamb: a strip of pixels there may take a probe from beyond it),
 * and a small object standing between them (a sphere on a floor) may be missed, as the
 * lecture's plane weights alone miss it. Every other probe (off the pixel's plane: a sphere's
 * pixel and a floor's probe) is refused: such pixels take the adaptive probes or trace their
 * own rays (screen_probe_fallback). */
bool probe_occ_visible(ivec2 q, vec3 b, vec3 nb, vec3 pa, float voxel)
{
  vec4 meta = texelFetch(probe_occ, ivec2(q.x * PROBE_OCC_TEXELS + PROBE_OCC_TEXELS - 1, q.y), 0);
  if (meta.w < 0.5) {
    return false;
  }
  vec3 d = pa - gi_lifted(b, nb, meta.x);
  float r = length(d);
  if (r > meta.z || abs(dot(d, nb)) > 0.25 * r + GI_HIT_VOXELS * max(voxel, meta.x)) {
    return false;
  }
  vec3 u, v;
  probe_occ_basis(nb, u, v);
  float a = atan(dot(d, v), dot(d, u));
  float k = (a < 0.0 ? a + 6.28318530718 : a) / PROBE_OCC_STEP;
  int k0 = int(floor(k)) % PROBE_OCC_AZIMUTHS;
  int k1 = (k0 + 1) % PROBE_OCC_AZIMUTHS;
  float f0 = texelFetch(probe_occ, ivec2(q.x * PROBE_OCC_TEXELS + k0 / 4, q.y), 0)[k0 % 4];
  float f1 = texelFetch(probe_occ, ivec2(q.x * PROBE_OCC_TEXELS + k1 / 4, q.y), 0)[k1 % 4];
  return r <= min(f0, f1);
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy) * px_step + px_phase;
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, px, vec4(0.0, 0.0, 0.0, -1.0));
    return;
  }
  /* the shading normal (a normal map's) for the irradiance; planes and weights keep n (turned
   * with n when gbuf_surface turned it to the camera) */
  vec3 ns = gbuf_shading_normal(px, n, shading_normals != 0);
  ns = dot(ns, n) < 0.0 ? -ns : ns;

  ivec2 atlas = textureSize(probe_info, 0);
  ivec2 grid = uniform_rows > 0 ? ivec2(atlas.x / 4, uniform_rows) : atlas;
  vec2 g = (vec2(px) + 0.5) / float(probe_tile) - 0.5;
  ivec2 i0 = ivec2(floor(g));
  vec2 f = g - vec2(i0);
  ivec2 q[4] = ivec2[4](i0, i0 + ivec2(1, 0), i0 + ivec2(0, 1), i0 + ivec2(1, 1));
  vec4 info[4];
  vec4 valid;
  float h;
  int obj;
  sdf_scene(p, h, obj);
  float voxel = gi_object_voxel(max(obj, 0));
  /* emitters facing the pixel from under 1.5 voxels: no probe ray reaches them */
  vec3 near = sc_near_emission(p, n, voxel);
  vec3 pa = gi_lifted(p, n, voxel);     /* where the probes' occlusion maps are read */
  for (int k = 0; k < 4; k++) {
    q[k] = clamp(q[k], ivec2(0), grid - 1);
    info[k] = texelFetch(probe_info, q[k], 0);
    vec3 nk = texelFetch(probe_normal, q[k], 0).xyz;
    valid[k] = info[k].w > 0.0 && dot(nk, n) > PROBE_NORMAL_MIN
               && probe_occ_visible(q[k], info[k].xyz, nk, pa, voxel) ? 1.0 : 0.0;
  }
  float depth = max(distance(p, cam_pos), 1e-4);
  float ok;
  vec4 w = probe_corner_weights(f, info[0].xyz, info[1].xyz, info[2].xyz, info[3].xyz, valid,
                                vec4(n, dot(n, p)), depth, ok);
  if (ok < 0.5 && uniform_rows > 0) {
    /* the adaptive probes of the 2x2 nearest 8x8 tiles and 4x4 tiles, by bilinear x plane
     * weights (screen_probe_adaptive placed them where the uniform ones fail) */
    vec3 Ea = vec3(0.0);
    float wa = 0.0;
    for (int level = 1; level <= 2; level++) {
      int T = probe_tile >> level;
      vec2 ga = (vec2(px) + 0.5) / float(T) - 0.5;
      ivec2 a0 = ivec2(floor(ga));
      vec2 fa = ga - vec2(a0);
      ivec2 origin = ivec2(0, level == 1 ? uniform_rows : 3 * uniform_rows);
      ivec2 extent = (level == 1 ? 2 : 4) * grid;
      for (int k = 0; k < 4; k++) {
        ivec2 c = ivec2(k & 1, k >> 1);
        ivec2 t = clamp(a0 + c, ivec2(0), extent - 1);
        ivec2 slot = origin + t;
        vec4 ai = texelFetch(probe_info, slot, 0);
        if (ai.w <= 0.0 || dot(texelFetch(probe_normal, slot, 0).xyz, n) <= PROBE_NORMAL_MIN) {
          continue;
        }
        float rel = abs(dot(vec4(ai.xyz, -1.0), vec4(n, dot(n, p)))) / depth;
        float wk = (c.x == 1 ? fa.x : 1.0 - fa.x) * (c.y == 1 ? fa.y : 1.0 - fa.y)
                   * exp2(-PROBE_PLANE_SHARPNESS * rel * rel) + 1e-6 * float(rel < 0.01);
        if (wk <= 0.0) {
          continue;
        }
        vec3 ca[9];
        for (int i = 0; i < 9; i++) {
          ca[i] = texelFetch(probe_sh, slot * 3 + ivec2(i % 3, i / 3), 0).rgb;
        }
        Ea += wk * sh9_irradiance(ca, ns);
        wa += wk;
      }
    }
    if (wa > 0.0) {
      imageStore(out_image, px, vec4(max(Ea / wa, vec3(0.0)) + near, 0.5));
      return;
    }
  }
  if (ok < 0.5) {
    vec4 bw = vec4((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
    bw *= valid;
    w = bw / max(dot(bw, vec4(1.0)), 1e-6);
    if (dot(valid, vec4(1.0)) == 0.0) {
      /* No probe this pixel can see (silhouettes, a strip along a thin wall): its own rays, in
       * screen_probe_fallback (the lecture refines with smaller probes; a pixel is the limit). */
      ivec2 block = px >> 2;
      if (fb_skip > 1 && (fb_turn + int(pcg_hash(uint(block.x) + 7919u * uint(block.y))
                                       % uint(fb_skip))) % fb_skip != 0) {
        /* not this 4x4 block's turn (fb_skip: screen_probe_fallback's skip, from the last
         * redraw's list): the history stays (w = -2), and the list holds only pixels that
         * trace, so the fallback's work groups are full of them */
        imageStore(out_image, px, vec4(near, -2.0));
        return;
      }
      imageStore(out_image, px, vec4(near, 0.0));
      int slot = imageAtomicAdd(fb_counter, ivec2(0, 0), 1);
      int lw = imageSize(fb_list).x;
      imageStore(fb_list, ivec2(slot % lw, slot / lw), vec4(vec2(px), voxel, 0.0));
      return;
    }
  }
  vec3 E = vec3(0.0);
  for (int k = 0; k < 4; k++) {
    if (w[k] <= 0.0) {
      continue;
    }
    vec3 c[9];
    for (int i = 0; i < 9; i++) {
      c[i] = texelFetch(probe_sh, q[k] * 3 + ivec2(i % 3, i / 3), 0).rgb;
    }
    E += w[k] * sh9_irradiance(c, ns);
  }
  imageStore(out_image, px, vec4(max(E, vec3(0.0)) + near, ok));
}
