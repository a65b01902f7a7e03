/* Lumen GI: irradiance from Blender's lights with SDF cone-traced soft shadows, and SDF-occluded
 * sky visibility (needs sdf_lib.glsl). Shared by the per-pixel direct pass and the surface cache.
 *
 * Inputs: sampler2D lights (RGBA32F, 4 texels per light row, operators/lights.py).
 * Shadows: SDF cone tracing, visibility = min over steps of k * d / t (k from the light's
 * angular size, clamped to [2, 16]), started OFFSET_VOXELS = 1 voxel off the surface along its
 * normal (2 voxels let light leak onto the floor along a box's shadowed base: Cycles relMSE 0.095
 * for the sun in tests/gpu/test_direct_light.py, 0.011 with 1), then smoothstep.
 * Sky: `cones` fixed cosine-distributed directions around the normal, each a wide cone (k = 2)
 * over 3 m; E_sky = pi * sky * mean visibility.
 */
#define PI 3.14159265358979
#define SHADOW_STEPS 96
#define OFFSET_VOXELS 1.0

vec4 light_texel(int i, int t)
{
  return texelFetch(lights, ivec2(t, i), 0);
}

float cone_visibility(vec3 p, vec3 n, vec3 dir, float t_max, float k)
{
  float h;
  int nearest;
  sdf_scene(p, h, nearest);
  vec3 o = p + n * (OFFSET_VOXELS * h);
  float t = 0.5 * h;
  float vis = 1.0;
  for (int i = 0; i < SHADOW_STEPS; i++) {
    float hv;
    float d = sdf_scene(o + dir * t, hv, nearest);
    vis = min(vis, k * d / t);
    if (vis <= 0.0) {
      return 0.0;
    }
    t += max(d, 0.2 * hv);
    if (t >= t_max) {
      break;
    }
  }
  vis = clamp(vis, 0.0, 1.0);
  return vis * vis * (3.0 - 2.0 * vis);
}

/* Irradiance E (W/m^2, rgb) at p with normal n from light i, shadowed. */
vec3 light_irradiance(int i, vec3 p, vec3 n)
{
  vec4 t0 = light_texel(i, 0);
  vec4 t1 = light_texel(i, 1);
  vec4 t2 = light_texel(i, 2);
  vec4 t3 = light_texel(i, 3);
  int type = int(t0.x + 0.5);
  vec3 L;
  float dist;
  vec3 E;
  float k;
  if (type == 0) {
    L = -t1.xyz;
    dist = 100.0;
    E = t2.rgb;
    k = 1.0 / max(tan(0.5 * t1.w), 1e-3);
  }
  else {
    vec3 to = t0.yzw - p;
    dist = length(to);
    L = to / max(dist, 1e-6);
    E = t2.rgb / max(dist * dist, 1e-8);
    float cos_l = dot(-L, t1.xyz);
    if (type == 2) {
      float cos_half = t3.x;
      float smooth_w = t3.y * (1.0 - cos_half);
      float s = smooth_w > 0.0 ? clamp((cos_l - cos_half) / smooth_w, 0.0, 1.0) :
                                 (cos_l > cos_half ? 1.0 : 0.0);
      E *= s * s * (3.0 - 2.0 * s);
    }
    else if (type == 3) {
      E *= max(cos_l, 0.0);
    }
    k = dist / max(t1.w, 1e-3);
  }
  float cos_s = dot(n, L);
  if (cos_s <= 0.0 || all(equal(E, vec3(0.0)))) {
    return vec3(0.0);
  }
  k = clamp(k, 2.0, 16.0);
  return E * cos_s * cone_visibility(p, n, L, dist, k);
}

float sky_visibility(vec3 p, vec3 n, int cones)
{
  vec3 a = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 u = normalize(cross(n, a));
  vec3 v = cross(n, u);
  float sum = 0.0;
  for (int i = 0; i < cones; i++) {
    /* Fibonacci points on the disk, lifted to the hemisphere: cosine distributed. */
    float r = sqrt((float(i) + 0.5) / float(cones));
    float phi = float(i) * 2.39996323;
    vec3 dir = normalize(u * (r * cos(phi)) + v * (r * sin(phi)) + n * sqrt(max(0.0, 1.0 - r * r)));
    sum += cone_visibility(p, n, dir, 3.0, 2.0);
  }
  return cones > 0 ? sum / float(cones) : 1.0;
}

