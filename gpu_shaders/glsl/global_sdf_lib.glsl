/* Lumen GI: sampling the global SDF (4 clipmap levels around the camera).
 *
 * Resources (declared by GlobalSDF.declare, bound by GlobalSDF.bind, gpu_shaders/global_sdf.py):
 *   sampler3D gsdf_level0..3   R16F/R32F, N^3, toroidally addressed (see global_sdf_build.comp.glsl)
 *   GlobalSDFParams gsdf  a uniform block: gsdf.origin[k].xyz the level's first world cell
 *                         (integers), .w its voxel size (m); values are clamped to
 *                         min(d, gsdf.band.x * voxel) per level
 * The hybrid trace (mesh SDFs near, global SDF far) is global_sdf_trace_lib.glsl. All reads are
 * texelFetch; the trilinear
 * filter is done here in float32 (the toroidal wrap rules out the hardware filter).
 */

#define GSDF_LEVELS 4
#define GSDF_MESH_SPLIT 1.8   /* metres: mesh SDFs before, the global SDF beyond (lecture 21) */
#define GSDF_FAR 1e30

/* a mod n in [0, n) for negative a too (GLSL % is undefined for negative operands). */
ivec3 gsdf_imod(ivec3 a, int n)
{
  return a - n * ivec3(floor(vec3(a) / float(n)));
}

vec4 gsdf_origin(int level)
{
  return gsdf.origin[level];
}

float gsdf_fetch(int level, ivec3 t)
{
  if (level == 0) { return texelFetch(gsdf_level0, t, 0).x; }
  if (level == 1) { return texelFetch(gsdf_level1, t, 0).x; }
  if (level == 2) { return texelFetch(gsdf_level2, t, 0).x; }
  return texelFetch(gsdf_level3, t, 0).x;
}

/* Trilinear sample of one level at world p; false when p is not inside the level's voxel centres. */
bool gsdf_level_sample(int level, vec3 p, out float d)
{
  vec4 info = gsdf_origin(level);
  int n = textureSize(gsdf_level0, 0).x;
  vec3 g = p / info.w - 0.5 - info.xyz;        /* relative cell coordinates, centres at integers */
  d = GSDF_FAR;
  if (any(lessThan(g, vec3(0.0))) || any(greaterThan(g, vec3(float(n - 1))))) {
    return false;
  }
  ivec3 i0 = min(ivec3(floor(g)), ivec3(n - 2));
  vec3 f = g - vec3(i0);
  ivec3 cell = ivec3(round(info.xyz)) + i0;
  ivec3 a = gsdf_imod(cell, n);
  ivec3 b = gsdf_imod(cell + 1, n);
  float c000 = gsdf_fetch(level, ivec3(a.x, a.y, a.z));
  float c001 = gsdf_fetch(level, ivec3(a.x, a.y, b.z));
  float c010 = gsdf_fetch(level, ivec3(a.x, b.y, a.z));
  float c011 = gsdf_fetch(level, ivec3(a.x, b.y, b.z));
  float c100 = gsdf_fetch(level, ivec3(b.x, a.y, a.z));
  float c101 = gsdf_fetch(level, ivec3(b.x, a.y, b.z));
  float c110 = gsdf_fetch(level, ivec3(b.x, b.y, a.z));
  float c111 = gsdf_fetch(level, ivec3(b.x, b.y, b.z));
  float c00 = mix(c000, c001, f.z);
  float c01 = mix(c010, c011, f.z);
  float c10 = mix(c100, c101, f.z);
  float c11 = mix(c110, c111, f.z);
  d = mix(mix(c00, c01, f.y), mix(c10, c11, f.y), f.x);
  return true;
}

/* Global SDF at world p from the finest level holding p; when that value is saturated at its
 * level's band, coarser levels (larger bands) are tried for a longer step. level: the level the
 * value came from (-1 and GSDF_FAR outside every level); voxel: its voxel size. */
float global_sdf_sample(vec3 p, out int level, out float voxel)
{
  float best = GSDF_FAR;
  level = -1;
  voxel = 1.0;
  for (int k = 0; k < GSDF_LEVELS; k++) {
    float d;
    if (!gsdf_level_sample(k, p, d)) {
      continue;
    }
    float vk = gsdf_origin(k).w;
    if (level < 0 || d > best) {
      best = d;
      level = k;
      voxel = vk;
    }
    if (d < 0.999 * gsdf.band.x * vk) {
      break;                 /* not saturated: the finest informative value */
    }
  }
  return best;
}

float global_sdf_sample(vec3 p)
{
  int level;
  float voxel;
  return global_sdf_sample(p, level, voxel);
}

