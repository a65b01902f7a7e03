#include "global_sdf_lib.glsl"
#include "voxel_lighting_layout_lib.glsl"
/* Lumen GI: voxel lighting, read at global-SDF hits (voxel_lighting_layout_lib.glsl says what a
 * voxel face holds and where; the tiles' object lists gi_trace searches are
 * voxel_lighting_trace_lib.glsl).
 *
 * sampler2D vl_radiance (and vl_tiles, voxel_lighting_trace_lib.glsl's), declared and bound by
 * voxel_lighting.py for the passes that include them. A vl_radiance narrower than 24 N (the 1x1 placeholder
 * bound when there is no voxel lighting) disables both: vl_sample fails everywhere,
 * vl_load_tile too, and gi_trace searches every object as before.
 */
bool vl_enabled()
{
  return textureSize(vl_radiance, 0).x >= GSDF_LEVELS * VL_FACES * textureSize(gsdf_level0, 0).x;
}

/* Whether the voxel at texel t (centre at r voxels from the lookup point: r = point - centre)
 * may light a ray travelling along dir that stopped at the point, on a surface of unit normal n
 * (0: unknown). Not when
 *   - its centre lies inside a solid (VL_INSIDE; its faces are empty anyway);
 *   - its centre lies behind the surface's plane, or more than VL_AHEAD voxels beyond the point
 *     along the ray: in a solid, or across a wall thinner than a voxel, in the room behind it;
 *   - along some axis, its face toward the point met a surface short of the point (by more than
 *     the thin-wall margin `eps`, in voxels): that surface separates them (a wall at an angle
 *     to the one hit, in a room's corner).
 * Trilinear weights do not see a wall thinner than a voxel: light from its other side, a voxel
 * away, leaked in (bench/quality.py's thin room: 2.7% of the lit luminance inside, against 0.5%
 * with the surface cache read at every hit, before these tests). */
#define VL_AHEAD 0.3
bool vl_usable(int level, ivec3 t, int n, vec3 r, vec3 dir, vec3 normal, float eps)
{
  if (gsdf_fetch(level, t) < VL_INSIDE * gsdf.band.y || dot(-r, dir) > VL_AHEAD
      || dot(-r, normal) < -eps) {
    return false;
  }
  for (int a = 0; a < 3; a++) {
    float ra = abs(r[a]);
    if (ra <= eps) {
      continue;
    }
    int f = 2 * a + (r[a] > 0.0 ? 0 : 1);
    float s = vl_face_offset(texelFetch(vl_radiance, vl_texel(level, f, t, n), 0).a);
    if (s > -eps && s < ra - eps) {
      return false;
    }
  }
  return true;
}

/* Radiance arriving along unit dir at world p (a hit in `level` on a surface of unit normal
 * `normal`, 0 if unknown): trilinear over the 8 voxels around p, of each the 3 faces the ray
 * travels along weighted by dir^2 (they sum to 1); faces without a lit surface and voxels that
 * may not light the ray (vl_usable) are left out and the weights renormalised. False when
 * nothing is left. */
bool vl_sample(int level, vec3 p, vec3 dir, vec3 normal, out vec3 L)
{
  L = vec3(0.0);
  if (level < 0 || !vl_enabled()) {
    return false;
  }
  int n = textureSize(gsdf_level0, 0).x;
  vec4 info = gsdf_origin(level);
  vec3 g = clamp(p / info.w - 0.5 - info.xyz, vec3(0.0), vec3(float(n - 1)));
  ivec3 i0 = min(ivec3(floor(g)), ivec3(n - 2));
  vec3 f = g - vec3(i0);
  ivec3 cell = ivec3(round(info.xyz)) + i0;
  ivec3 face = ivec3(dir.x >= 0.0 ? 0 : 1, dir.y >= 0.0 ? 2 : 3, dir.z >= 0.0 ? 4 : 5);
  vec3 dw = dir * dir;
  float eps = gsdf.band.y / info.w + 0.02;
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  for (int k = 0; k < 8; k++) {
    ivec3 c = ivec3(k & 1, (k >> 1) & 1, k >> 2);
    vec3 b = mix(vec3(1.0) - f, f, vec3(c));
    float tri = b.x * b.y * b.z;
    if (tri <= 0.0) {
      continue;
    }
    ivec3 t = gsdf_imod(cell + c, n);
    if (!vl_usable(level, t, n, f - vec3(c), dir, normal, eps)) {
      continue;
    }
    for (int a = 0; a < 3; a++) {
      vec4 r = texelFetch(vl_radiance, vl_texel(level, face[a], t, n), 0);
      float w = r.a > 0.0 ? tri * dw[a] : 0.0;
      sum += w * r.rgb;
      wsum += w;
    }
  }
  if (wsum < 1e-6) {
    return false;
  }
  L = sum / wsum;
  return true;
}

