#include "sdf_lib.glsl"
/* Lumen GI: irradiance from Blender's lights with SDF cone-traced soft shadows (needs
 * sdf_lib.glsl). Shared by the per-pixel direct pass and the surface cache.
 *
 * Inputs: sampler2D lights (RGBA32F, 4 texels per light row, operators/lights.py).
 * Shadows: SDF cone tracing, visibility = min over steps of k * (d - m voxel) / t (k from the
 * light's angular size, 1 / tan(half angle), clamped to [2, 256]: Blender's default sun is 215,
 * a clamp at 16 spread its penumbra over 20 cm at 3 m and halved a window's sun patch; the half
 * voxel m is the thin-wall rule: a wall thinner than a voxel never reaches d = 0; on a mesh with
 * depth under every surface the field's measured rounding of its convex edges, at most 0.25:
 * light_thin), from the surface
 * itself (cone_visibility: samples that only leave the receiver's own surface do not occlude;
 * the earlier start one voxel along the normal shifted shadows: sun relMSE 0.0125 against
 * 0.0024 in tests/gpu/test_direct_light.py), then smoothstep.
 * cone_visibility also serves the direct pass's sky light (direct_light.comp.glsl: wide cones,
 * k = 2, over 3 m).
 */
#define PI 3.14159265358979
#define SHADOW_STEPS 96
#define LIGHT_SUN_REACH 100.0
#define SDF_BAND_VOXELS 4.0   /* lumen_addon/sdf.py BAND_VOXELS */
#define THIN_VOXELS 0.5   /* occluders count half a voxel thicker: walls thinner than a voxel block */

vec4 light_texel(int i, int t)
{
  return texelFetch(lights, ivec2(t, i), 0);
}

/* The thin-wall margin (voxels) of the object nearest a cone sample: THIN_VOXELS, or for a mesh
 * whose field has depth under every surface the field's rounding of its convex edges as the bake
 * measured it, at most 0.25 (gpu_shaders/packing.py thin_voxels, edge_voxels: there the field
 * crosses zero at the surface, and the half voxel only shrank openings: a window's sun patch
 * lost 19%, a fixed quarter voxel 7%). */
float light_thin(int obj)
{
  return obj >= 0 ? sdf_object_texel(obj, 9).x : THIN_VOXELS;
}

/* t_shell: where the receiver's own half-voxel shell ends along dir (0 for the lights' narrow
 * cones; the sky's wide cones measure their opening from there, so a surface that only curves
 * away, a sphere or open ground, is not occluded by the thin-wall rule: see sky_light). */
float cone_visibility_shell_(vec3 p, vec3 n, vec3 dir, float t_max, float k, float t_shell)
{
  float h;
  int nearest;
#ifdef LIGHT_CUT_OUTS
  sdf_part_d = 1e30;
  sdf_part_obj = -1;
  float d0 = sdf_scene(p, h, nearest);
  if (sdf_part_obj >= 0 && sdf_part_d < d0) {
    h = sdf_object_texel(sdf_part_obj, 4).w * sdf_object_texel(sdf_part_obj, 7).w;  /* a leaf */
  }
#else
  sdf_scene(p, h, nearest);
#endif
  /* The cone starts on the surface (a hair off it), not a voxel along the normal: that offset
   * moved shadow edges by voxel / tan(elevation), 7 cm for a 35 degree sun on 5 cm voxels. While
   * the cone is only leaving its own surface (the field below the thin-wall shell and rising
   * steadily) it does not count as occluded; once the field stops rising (another surface
   * ahead: a wall next to the receiver) or clears the shell, every sample counts. */
  vec3 o = p + n * (0.05 * h);
  float t = 0.25 * h;
  /* shell mode: a receiver the SDF has slightly inside its surface (the baked field is off the
   * polygons by a fraction of a voxel) would read that offset as an occluder at every step */
  float lift = 0.0;
  if (t_shell > 0.0) {
    float hv0;
    lift = max(-sdf_scene(o, hv0, nearest), 0.0);
  }
  float vis = 1.0;
  /* Cut-outs (sdf_lib.glsl sdf_part_*; compiled in only for a scene that has one,
   * compute.VARIANTS: LIGHT_CUT_OUTS): `through` is the product of their shadow shares over the
   * shells the cone crosses (in_part: inside one now; the first sample's is the receiver's own,
   * a leaf, not counted). Evenly: the holes' pattern is not cast, as UE's foliage distance
   * fields shadow partly. This bookkeeping in the one loop: a second march over the cut-outs,
   * even one never run, made the direct pass 1.57x on llvmpipe (bench/glsl_ab.py: the shader's
   * size). */
  float through = 1.0;
#ifdef LIGHT_CUT_OUTS
  bool in_part = false;
#endif
  bool leaving = true;
  float last = -1e30;
  float t_last = 0.0;
  /* Past t_out, where the cone's axis leaves the object grid's box grown by its margin M (at
   * least 4 voxels of the coarsest object), no sample can lower vis: there d >= M + (t - t_out) c
   * (c: the axis's cosine to the exit face), so k (d - thin) / t >= k min(7 M / (8 t_out), c)
   * (thin <= half a voxel <= M / 8); and a wide cone's sample beyond the band does not count. */
  float margin = sdf_grid_texel(2).x;
  float c;
  vec2 span = sdf_scene_box_span(o, dir, margin, c);
  float t_out = max(span.y, 0.0);
  float past = k * min(0.875 * margin / max(t_out, 1e-6), c);
  for (int i = 0; i < SHADOW_STEPS; i++) {
    if (t >= t_out && (t_shell > 0.0 || past >= vis)) {
      break;
    }
    float hv;
#ifdef LIGHT_CUT_OUTS
    sdf_part_d = 1e30;
    sdf_part_obj = -1;
#endif
    float d = sdf_scene(o + dir * t, hv, nearest);
    float stride = max(d, 0.2 * hv);
#ifdef LIGHT_CUT_OUTS
    {
      int po = sdf_part_obj;
      bool inside = false;
      if (po >= 0) {
        float pv = sdf_object_texel(po, 4).w * sdf_object_texel(po, 7).w;
        inside = sdf_part_d < light_thin(po) * pv;
        if (inside && !in_part && i > 0) {
          through *= sdf_object_texel(po, 9).y;
        }
        /* through a shell in half voxels; up to it no farther than its surface */
        stride = min(stride, max(inside ? 0.5 * pv : sdf_part_d, 0.2 * pv));
      }
      in_part = inside;
    }
#endif
    if (leaving) {
      /* leaving means the field rises by a tenth of the distance travelled or more: the flat
       * field inside a wall thinner than a voxel does not, so such a wall still occludes.
       * Within half a voxel of the receiver's own plane the cone is leaving whatever the field
       * does: a two-sided surface (|d| - half a voxel) midway between two samples reads a flat
       * 0 over a whole voxel, and that plateau counted as an occluder on the receiver itself
       * (an imported room's floor, baked two-sided, got no direct light at all). */
      bool rising = d >= last + 0.1 * (t - t_last) || t * dot(dir, n) < 0.5 * hv;
      if (rising && d < (THIN_VOXELS + 0.5) * hv) {
        last = d;
        t_last = t;
        t += min(max(0.5 * d, 0.2 * hv), stride);
        if (t >= t_max) {
          break;
        }
        continue;
      }
      leaving = false;
    }
    /* shell mode: a sample farther from every surface than the SDF's band (4 voxels; the
     * field there is clamped to the band, a lower bound) says nothing about a wide cone: k x
     * band / t would shrink with t alone and darken open sky (a sphere lost 10% of it) */
    if (t_shell <= 0.0 || d < (SDF_BAND_VOXELS - 0.5) * hv) {
      vis = min(vis, k * (d + lift - light_thin(nearest) * hv) / max(t - t_shell, 0.25 * t));
    }
    if (vis <= 0.0) {
      return 0.0;
    }
    t += stride;
    if (t >= t_max) {
      break;
    }
  }
  vis = clamp(vis, 0.0, 1.0);
  return vis * vis * (3.0 - 2.0 * vis) * through;
}

/* ... with the instances that cast no shadow left out (sdf_lib.glsl: sdf_shadow_rays) */
float cone_visibility_shell(vec3 p, vec3 n, vec3 dir, float t_max, float k, float t_shell)
{
  sdf_shadow_rays = true;
  float vis = cone_visibility_shell_(p, n, dir, t_max, k, t_shell);
  sdf_shadow_rays = false;
  return vis;
}

float cone_visibility(vec3 p, vec3 n, vec3 dir, float t_max, float k)
{
  return cone_visibility_shell(p, n, dir, t_max, k, 0.0);
}

/* The direct pass's sky cones (direct_light.comp.glsl: sky_light): cone i of `cones` is a
 * Fibonacci point on the disk, lifted to the hemisphere (cosine distributed) around n
 * (tangents u, v from sky_cone_basis), traced SKY_CONE_REACH with k = sky_cone_k. */
#define SKY_CONE_REACH 3.0
void sky_cone_basis(vec3 n, out vec3 u, out vec3 v)
{
  vec3 a = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  u = normalize(cross(n, a));
  v = cross(n, u);
}

vec3 sky_cone_dir(int i, int cones, vec3 n, vec3 u, vec3 v)
{
  float r = sqrt((float(i) + 0.5) / float(cones));
  float phi = float(i) * 2.39996323;
  return normalize(u * (r * cos(phi)) + v * (r * sin(phi)) + n * sqrt(max(0.0, 1.0 - r * r)));
}

float sky_cone_k(vec3 dir, vec3 n)
{
  return max(2.0, 1.0 / max(dot(dir, n), 0.05));
}

/* A per-pixel rotation in [0,1)^2 for the light samples (integer hash of the pixel). */
vec2 light_rotation(ivec2 px)
{
  uint h = uint(px.x) * 1973u + uint(px.y) * 9277u + 26699u;
  h = (h ^ (h >> 16u)) * 0x7feb352du;
  h = (h ^ (h >> 15u)) * 0x846ca68bu;
  h ^= h >> 16u;
  return vec2(float(h & 0xffffu), float(h >> 16u)) / 65536.0;
}

/* Irradiance E (W/m^2, rgb) at p with normal n from light i, shadowed.
 * Sun: one cone as wide as the sun's disk. Point, spot and area lights with a radius: `samples`
 * stratified points on a disk of that radius (facing p for point and spot lights, which are
 * spheres in Cycles; the area light's own plane), rotated by rot; each point gets a cone as wide
 * as its share of the light (k = distance / (radius / sqrt(samples))), and their mean is the
 * soft shadow: a penumbra that grows from the shadow edge both ways, as a path tracer's does,
 * where one cone over the whole light darkens from the edge outwards only. */
vec3 light_irradiance_part(int i, vec3 p, vec3 n, vec3 ns, int samples, vec2 rot, int first,
                           int take);

/* Where a cone towards a light sample `dist` away with a share of radius `sub` ends (what is
 * right behind the light casts nothing), and its k. */
float light_reach(float dist, float sub)
{
  return max(dist - sub, 0.5 * dist);
}

float light_k(float dist, float sub)
{
  return clamp(dist / max(sub, 1e-3), 2.0, 256.0);
}

/* A sun's k (its disk's half angle in t1.w). */
float light_sun_k(vec4 t1)
{
  return clamp(1.0 / max(tan(0.5 * t1.w), 1e-3), 2.0, 256.0);
}

/* true for a light whose every part is the whole light (a sun, a light without radius): the
 * viewport's progressive direct light evaluates it once, not once per part */
bool light_single(int i)
{
  vec4 t0 = light_texel(i, 0);
  return int(t0.x + 0.5) == 0 || light_texel(i, 1).w <= 0.005;
}

/* Sample point s of `count` on light i's disk (centre, radius r: facing p for point and spot
 * lights, the area light's own plane), rotated by rot: the points light_irradiance_part shades
 * and the viewport's restart test (direct_restart.comp.glsl) follows. */
vec3 light_point(int i, vec3 p, int s, int count, vec2 rot)
{
  vec4 t0 = light_texel(i, 0);
  vec4 t1 = light_texel(i, 1);
  vec3 centre = t0.yzw;
  float r = t1.w;
  vec3 axis = int(t0.x + 0.5) == 3 ? t1.xyz : (centre - p) / max(length(centre - p), 1e-6);
  vec3 a = abs(axis.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 bu = normalize(cross(axis, a));
  vec3 bv = cross(axis, bu);
  vec2 u = fract(vec2((float(s) + 0.5) / float(count), float(s) * 0.618033988749895) + rot);
  float rr = count > 1 ? r * sqrt(u.x) : 0.0;
  float phi = 6.28318530717958648 * u.y;
  return centre + rr * (cos(phi) * bu + sin(phi) * bv);
}

/* Cycles' bump shadowing term (Conty Estevez et al. 2019, "A Microfacet-Based Shadowing Function
 * to Solve the Bump Terminator Problem"; Blender 4.x and 5.0), which it applies to a diffuse BSDF
 * whose shading normal ns (a normal map's, a bump's) is not the smooth normal n: the bumps are
 * taken for GGX microfacets of alpha^2 = tan^2(n, ns) / 8 and the light is shadowed by their
 * Smith G1 at its angle to n; a direction on the other side of n than ns is black. 1 when ns is
 * n. Measured against Cycles' Diffuse Direct (tests/gpu/test_normal_maps.py, test_bump.py): a
 * 30-degree map or bump under a 52-degree sun 0.7% over (Chiang et al.'s term, Cycles' before
 * 4.0, read 6.7% under), a 40-degree map 1.1% over (1.0% under). */
float bump_shadowing(vec3 n, vec3 ns, vec3 L)
{
  float cos_d = abs(dot(n, ns));
  float cos_i = abs(dot(n, L));
  if (dot(n, L) * dot(n, ns) * dot(ns, L) < 0.0) {
    return 0.0;
  }
  if (cos_d >= 0.99999 || cos_i >= 1.0) {
    return 1.0;
  }
  if (cos_i < 1e-6) {
    return 0.0;
  }
  float alpha2 = clamp(0.125 * (1.0 / (cos_d * cos_d) - 1.0), 0.0, 1.0);
  float tan2_i = 1.0 / (cos_i * cos_i) - 1.0;
  return 2.0 / (1.0 + sqrt(1.0 + alpha2 * tan2_i));
}

/* Samples light i takes (1 for a light without radius). */
int light_count_of(int i, int samples)
{
  return light_texel(i, 1).w > 0.005 ? max(samples, 1) : 1;
}

vec3 light_irradiance(int i, vec3 p, vec3 n, int samples, vec2 rot)
{
  return light_irradiance_part(i, p, n, n, samples, rot, 0, samples);
}

/* Irradiance per unit intensity from a uniformly emitting sphere of radius r whose centre is
 * dc away, at cosine cos_c from the receiver's normal: cos_c / dc^2 (a point light's) while it is
 * all above the receiver's horizon; where the horizon cuts it, the exact form factor of the cap
 * above (the closed form of a sphere's irradiance with horizon clipping, as in Snyder 1996 and
 * Frostbite's "Moving to PBR"), over pi r^2 (the intensity of a sphere of unit radiance).
 * tests/gpu/test_light_falloff.py: a patch whose horizon cuts a sphere light read 41% under
 * Cycles when the samples below it were dropped. */
float light_sphere_factor(float cos_c, float r, float dc)
{
  float s2 = clamp(r * r / max(dc * dc, 1e-12), 1e-8, 1.0);    /* sin^2 of its angular radius */
  if (cos_c * cos_c >= s2) {
    return max(cos_c, 0.0) / max(dc * dc, 1e-8);
  }
  float sin_c = sqrt(max(1.0 - cos_c * cos_c, 1e-12));
  float x = sqrt(max(1.0 / s2 - 1.0, 0.0));
  float y = clamp(-x * cos_c / sin_c, -1.0, 1.0);
  float q = sin_c * sqrt(1.0 - y * y);
  float f = (cos_c * acos(y) - x * q) * s2 + atan(q, x);
  return max(f, 0.0) / (3.14159265 * max(r * r, 1e-12));
}

/* light_irradiance from `take` of the light's `samples` strata, starting at stratum `first`
 * (wrapping): the viewport spreads a light's samples over redraws (direct_light.py), and the mean
 * of the parts of consecutive redraws that cover every stratum once is light_irradiance exactly
 * (each sample keeps the cone width of `samples`). n: the geometric normal (the cones' start
 * and what faces the light), ns: the shading normal (a normal map's; the cosine). A light with one sample (a sun, a point light
 * without radius) returns its whole light from every part. */
vec3 light_irradiance_part(int i, vec3 p, vec3 n, vec3 ns, int samples, vec2 rot, int first,
                           int take)
{
  vec4 t0 = light_texel(i, 0);
  vec4 t1 = light_texel(i, 1);
  vec4 t2 = light_texel(i, 2);
  vec4 t3 = light_texel(i, 3);
  int type = int(t0.x + 0.5);
  if (type == 0) {
    vec3 L = -t1.xyz;
    float cos_s = dot(ns, L) * bump_shadowing(n, ns, L);
    if (cos_s <= 0.0 || dot(n, L) <= 0.0) {
      return vec3(0.0);
    }
    return t2.rgb * cos_s * (t2.w > 0.5 ? 1.0 : cone_visibility(p, n, L, LIGHT_SUN_REACH,
                                                                light_sun_k(t1)));
  }
  float r = t1.w;
  int count = light_count_of(i, samples);
  float sub = r / sqrt(float(count));            /* radius of each sample's share of the light */
  vec3 sum = vec3(0.0);
  int n_take = clamp(take, 1, count);
  /* Cycles' point and spot light with a radius: with Soft Falloff (its default; texel 3 z 1)
   * the disk facing p, each point seen at its cosine to the disk: I / (d^2 + r^2) on the axis;
   * without it a sphere, whose light (light_sphere_factor) the samples only shadow. Measured: a
   * 0.25 m light 0.4 m over a floor read 9% over Cycles' soft falloff below it, 20% under its
   * sphere (tests/gpu/test_light_falloff.py). Both need the centre's direction lc, the same
   * for every sample. */
  bool round_light = type <= 2 && r > 0.0;
  bool sphere = round_light && t3.z <= 0.5;
  vec3 c = t0.yzw - p;
  float dc = length(c);
  vec3 lc = c / max(dc, 1e-6);
  vec3 E_sphere = sphere ? t2.rgb * light_sphere_factor(dot(ns, lc), r, dc) : vec3(0.0);
  float cos_sphere = sphere ? bump_shadowing(n, ns, lc) : 0.0;
  int above = 0;                  /* the samples above the horizon: a sphere's shadow is theirs */
  for (int j = 0; j < n_take; j++) {
    vec3 q = light_point(i, p, (first + j) % count, count, rot);
    vec3 to = q - p;
    float dist = length(to);
    vec3 L = to / max(dist, 1e-6);
    float cos_s = dot(ns, L) * bump_shadowing(n, ns, L);
    if (cos_s <= 0.0 || dot(n, L) <= 0.0) {
      continue;
    }
    above++;
    vec3 E = t2.rgb / max(dist * dist, 1e-8);
    if (sphere) {
      E = E_sphere;
      cos_s = cos_sphere;
    }
    else if (round_light) {
      E *= max(dot(L, lc), 0.0);
    }
    float cos_l = dot(-L, t1.xyz);
    if (type == 2) {
      float cos_half = t3.x;
      float smooth_w = t3.y * (1.0 - cos_half);
      float m = smooth_w > 0.0 ? clamp((cos_l - cos_half) / smooth_w, 0.0, 1.0) :
                                 (cos_l > cos_half ? 1.0 : 0.0);
      E *= m * m * (3.0 - 2.0 * m);
    }
    else if (type == 3) {
      E *= max(cos_l, 0.0);
      if (t3.w >= 0.0 && cos_l > 0.0) {   /* Spread (operators/lights.py: spread_of) */
        float tan_a = sqrt(max(1.0 - cos_l * cos_l, 0.0)) / cos_l;
        E *= max(1.0 - tan_a / max(t3.w, 1e-4), 0.0);
      }
    }
    if (all(equal(E, vec3(0.0)))) {
      continue;
    }
    /* the cone stops where the light begins: what is right behind it (the ceiling an area
     * light hangs under) casts nothing */
    float reach = light_reach(dist, sub);
    float k = light_k(dist, sub);
    sum += E * cos_s * (t2.w > 0.5 ? 1.0 : cone_visibility(p, n, L, reach, k));  /* w: no shadow */
  }
  return sum / float(sphere ? max(above, 1) : n_take);
}
