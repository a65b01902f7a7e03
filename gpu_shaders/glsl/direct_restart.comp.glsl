/* The viewport's progressive direct light: which pixels start their parts again
 * (direct_light.py: Progressive).
 *
 * Inputs: gbuf_position, gbuf_normal, gbuf_albedo, gbuf_emission (gbuffer.glsl), lights
 * (operators/lights.py rows, 4 texels each), regions (RGBA32F, 2 texels per box: lo, hi; world
 * boxes outside which the scene SDF returns what it did when the pixels' shadows were traced:
 * SceneResources.regions_since), push constants cam_pos, light_count, region_count, sky_cones,
 * full (1: every pixel starts again), light_samples (direct_light.LIGHT_SAMPLES).
 * Read and written: signature (R32I: a 32-bit hash of the G-buffer the pixel was shaded from,
 * its position, normal, albedo and emission; 4 bytes a pixel, where the texels themselves took
 * 16), parts (the parts of the pixel's running mean, 0 to start again).
 *
 * A pixel starts again where its G-buffer differs, or where a cone the direct pass traces from
 * it may sample inside a region (sdf_scene is sampled only on a cone's axis): each light's
 * cones from the same start towards the same sample points (light_lib.glsl: light_point), and
 * with sky cones (GI Off) each of those. A region reaching the grid's faces is unbounded there
 * (a sample outside the grid reads the cell it clamps into), but a cone stops where it leaves
 * the grid's grown box whenever no sample beyond could lower its visibility (light_lib.glsl:
 * past >= vis; always for the sky's cones): such cones are tested only up to there.
 * Everywhere else every sample the direct pass takes is the same as before, so its kept mean
 * is what a restart would compute again: the converged image is the same as after a full
 * restart, and one object dragged among many costs the direct light of the pixels whose cones
 * pass near it, not of the whole view. The regions (around the object grid's cells whose list
 * or bound changed: in a sparse scene all of the moved object's reach, 4 grid margins) are what
 * that exactness costs: there they are metres wide.
 */
#include "sdf_lib.glsl"
#include "light_lib.glsl"

/* Whether segment a -> b meets box [lo, hi] (slabs; bounds may be +-1e30). */
bool segment_meets_box(vec3 a, vec3 b, vec3 lo, vec3 hi)
{
  vec3 d = b - a;
  float t0 = 0.0;
  float t1 = 1.0;
  for (int k = 0; k < 3; k++) {
    if (abs(d[k]) < 1e-12) {
      if (a[k] < lo[k] || a[k] > hi[k]) {
        return false;
      }
      continue;
    }
    float ta = (lo[k] - a[k]) / d[k];
    float tb = (hi[k] - a[k]) / d[k];
    t0 = max(t0, min(ta, tb));
    t1 = min(t1, max(ta, tb));
    if (t0 > t1) {
      return false;
    }
  }
  return true;
}

/* Whether the samples of a shadow cone from o along dir up to t_max (k: light_lib.glsl's) may
 * lie in a region: the cone stops where it leaves the grid's box grown by its margin whenever
 * no sample beyond could lower its visibility (past >= 1 >= vis), as cone_visibility_shell_
 * computes it from the same o. */
bool cone_meets_regions(vec3 o, vec3 dir, float t_max, float k)
{
  float margin = sdf_grid_texel(2).x;
  float c;
  float t_out = max(sdf_scene_box_span(o, dir, margin, c).y, 0.0);
  float past = k * min(0.875 * margin / max(t_out, 1e-6), c);
  vec3 b = o + (past >= 1.0 ? min(t_max, t_out) : t_max) * dir;
  for (int r = 0; r < region_count; r++) {
    if (segment_meets_box(o, b, texelFetch(regions, ivec2(0, r), 0).xyz,
                          texelFetch(regions, ivec2(1, r), 0).xyz)) {
      return true;
    }
  }
  return false;
}

/* Whether a shadow cone the direct pass traces from p (normal n, pixel px) may sample a region:
 * the light_irradiance_part cones, each from the same start and towards the same points. */
bool shadows_meet_regions(vec3 p, vec3 n, ivec2 px)
{
  float h;
  int nearest;
  sdf_scene(p, h, nearest);
  vec3 o = p + n * (0.05 * h);       /* cone_visibility_shell_'s start */
  for (int i = 0; i < light_count; i++) {
    vec4 t0 = light_texel(i, 0);
    vec4 t1 = light_texel(i, 1);
    if (light_texel(i, 2).w > 0.5) {
      continue;                      /* casts no shadow */
    }
    if (int(t0.x + 0.5) == 0) {
      if (dot(n, -t1.xyz) > 0.0 && cone_meets_regions(o, -t1.xyz, LIGHT_SUN_REACH,
                                                      light_sun_k(t1))) {
        return true;
      }
      continue;
    }
    int count = light_count_of(i, light_samples);
    float sub = t1.w / sqrt(float(count));
    for (int s = 0; s < count; s++) {
      vec3 to = light_point(i, p, s, count, light_rotation(px)) - p;
      float dist = length(to);
      vec3 L = to / max(dist, 1e-6);
      if (dot(n, L) > 0.0 && cone_meets_regions(o, L, light_reach(dist, sub),
                                                light_k(dist, sub))) {
        return true;
      }
    }
  }
  if (sky_cones > 0) {                /* sky_light's cones (wide: they always stop at t_out) */
    vec3 u, v;
    sky_cone_basis(n, u, v);
    for (int i = 0; i < sky_cones; i++) {
      vec3 dir = sky_cone_dir(i, sky_cones, n, u, v);
      if (cone_meets_regions(o, dir, SKY_CONE_REACH, 1e30)) {
        return true;
      }
    }
  }
  return false;
}

/* One 32-bit word mixed into the hash h (a multiply-xorshift avalanche per word). */
uint signature_mix(uint h, uint w)
{
  uint x = h ^ w;
  x ^= x >> 16u;
  x *= 0x7feb352du;
  x ^= x >> 15u;
  x *= 0x846ca68bu;
  x ^= x >> 16u;
  return x + 0x9e3779b9u;
}

uint signature_of(vec4 pos, vec3 n, vec3 albedo, vec3 emission)
{
  uvec4 a = floatBitsToUint(pos);
  uvec3 b = floatBitsToUint(n);
  uvec3 c = floatBitsToUint(albedo);
  uvec3 d = floatBitsToUint(emission);
  uint h = 0x2545f491u;
  h = signature_mix(signature_mix(signature_mix(signature_mix(h, a.x), a.y), a.z), a.w);
  h = signature_mix(signature_mix(signature_mix(h, b.x), b.y), b.z);
  h = signature_mix(signature_mix(signature_mix(h, c.x), c.y), c.z);
  return signature_mix(signature_mix(signature_mix(h, d.x), d.y), d.z);
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(parts);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec4 pos = texelFetch(gbuf_position, px, 0);
  vec3 n = texelFetch(gbuf_normal, px, 0).xyz;
  vec3 albedo = texelFetch(gbuf_albedo, px, 0).rgb;
  vec3 emission = texelFetch(gbuf_emission, px, 0).rgb;
  int sig = int(signature_of(pos, n, albedo, emission));
  bool again = full != 0 || sig != imageLoad(signature, px).r;
  if (!again && pos.w >= 0.5 && region_count > 0) {
    vec3 nn = normalize(n);
    if (dot(nn, cam_pos - pos.xyz) < 0.0) {
      nn = -nn;                      /* the side the direct pass shades */
    }
    again = shadows_meet_regions(pos.xyz, nn, px);
  }
  if (again) {
    imageStore(parts, px, vec4(0.0));
  }
  imageStore(signature, px, ivec4(sig));
}
