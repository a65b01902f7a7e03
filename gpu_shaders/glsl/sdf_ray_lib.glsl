#include "sdf_lib.glsl"
/* Lumen GI: short mesh-SDF rays (needs sdf_lib.glsl): the thin-wall hit rule, object voxels and
 * the visibility test of probe interpolation. Used by gi_trace_lib.glsl and the passes that only
 * need to know whether a wall lies between two points.
 * Thin walls: a hit is any point within GI_HIT_VOXELS = 0.5 voxel of the SDF surface. A wall
 * thinner than a voxel never has negative samples, but trilinear filtering of its samples stays
 * below half a voxel on the wall (for samples a fraction f of a voxel from it: 2 f (1 - f) <= 0.5),
 * so no ray passes it: the lecture's "expand the surface by half a voxel", done at trace time
 * for every mesh, over-occluding by that half voxel instead of leaking.
 */
#define GI_HIT_VOXELS 0.5
#define GI_MESH_STEPS 96

/* Sphere tracing o + t dir over [t0, t1] through every mesh SDF (sdf_scene): a hit is the first
 * sample within GI_HIT_VOXELS of a surface (the thin-wall rule above), also at t0: a ray that
 * starts inside a surface's shell (a probe in a concave corner, within half a voxel of the wall
 * beside its floor) hits that surface at once. Measured, a rule that let such a ray go on unless
 * it approached the surface (written in December, but its first sample always hit, so it never
 * ran): made to work, bench/quality.py's relMSE rose on thin by 38%, window 8%, imported 6%
 * (rays from corners passed through the wall beside them). */
bool gi_trace_mesh(vec3 o, vec3 dir, float t0, float t1, out float t, out int obj)
{
  t = t0;
  obj = -1;
  for (int i = 0; i < GI_MESH_STEPS; i++) {
    float h;
    int nearest;
    float d = sdf_scene(o + t * dir, h, nearest);
    if (d <= GI_HIT_VOXELS * h) {
      obj = nearest;
      return true;
    }
    t += max(d, 0.1 * h);
    if (t > t1) {
      break;
    }
  }
  return false;
}

/* Directions in which the scene SDF rises at a and at b: tetrahedral differences (four samples
 * at the corners (+-1, +-1, +-1) x half a voxel, as accurate as central differences, which took
 * six). ga is a's memo (w = 1 once computed): a pass that tests one end against several (a hit
 * against its card texels, a pixel against its probes) samples that end once. So 4 samples a
 * test, not the 12 of central differences at both ends, which cost 18% of a viewport frame among
 * 1,000 spheres (texels under a sphere resting on the floor: both lifted ends in the floor's
 * shell). bench/glsl_ab.py --objects 1000: frame 0.91x, 10 objects 0.99x; quality.py's images
 * the same (forward differences from the ends' own fields, 3 samples a test, made glow 0.5%
 * darker: a wall's field is not linear over half a voxel).
 * The samples come from one loop, one sdf_scene call site: inlined copies made every shader
 * that tests visibility slower, even where no lane takes this path (measured: 44% of a viewport
 * probe trace, whose surface-cache lookups test visibility per texel). */
void gi_scene_gradients(vec3 a, vec3 b, float voxel, inout vec4 ga, out vec3 gb)
{
  float h;
  int o;
  vec3 g[2] = vec3[2](vec3(0.0), vec3(0.0));
  for (int k = ga.w > 0.5 ? 4 : 0; k < 8; k++) {
    /* the tetrahedron (1,-1,-1), (-1,-1,1), (-1,1,-1), (1,1,1) */
    int i = k & 3;
    vec3 c = vec3((i == 0 || i == 3) ? 1.0 : -1.0, i < 2 ? -1.0 : 1.0,
                  (i == 1 || i == 3) ? 1.0 : -1.0);
    g[k >> 2] += c * sdf_scene((k < 4 ? a : b) + (0.5 * voxel) * c, h, o);
  }
  if (ga.w <= 0.5) {
    ga = vec4(g[0], 1.0);
  }
  gb = g[1];
}

/* World voxel edge of object obj (the unit of ray offsets off its surface). */
float gi_object_voxel(int obj)
{
  return sdf_object_texel(obj, 4).w * sdf_object_texel(obj, 7).w;
}

/* Whether light gathered at b may be used at a (nearby points on surfaces with normals na, nb):
 * both lifted GI_LIFT_VOXELS off their surfaces, the segment between them must not meet a surface
 * (gi_trace_mesh, the thin-wall rule included). Interpolating probes across a wall is how light
 * leaks into a closed room that stands on a lit floor. The segment is traced from the end with
 * more room around it; an end that is itself near a surface (a concave corner: floor and wall
 * within a voxel) ignores the last half voxel + a quarter before it, else every corner would
 * hide all its probes (measured: a closed room lost 4% of its light that way). */
#define GI_LIFT_VOXELS 1.5
#ifndef GI_STOP_MARGIN
#define GI_STOP_MARGIN 0.0
#endif
/* a's end lifted (gi_visible's pa) and the scene distance there: a pass that tests one point
 * against several (its 2x2 or 3x3 neighbours, all with one voxel) samples the field at pa once
 * and calls gi_visible_from; gi_visible is that for one pair. */
vec3 gi_lifted(vec3 a, vec3 na, float voxel)
{
  return a + na * (GI_LIFT_VOXELS * voxel);
}

/* Surface point p's lifted end (gi_lifted with the voxel of the object nearest p) and the scene
 * field there: what a pass that tests p against several neighbours (AA resolve, probe links,
 * probe occlusion maps) computes once before its tests. */
vec3 gi_lifted_end(vec3 p, vec3 n, out float voxel, out float field)
{
  float h;
  int obj;
  sdf_scene(p, h, obj);
  voxel = gi_object_voxel(max(obj, 0));
  vec3 end = gi_lifted(p, n, voxel);
  field = sdf_scene(end, h, obj);
  return end;
}

/* gi_visible_from with both lifted ends and their fields given (a pass that keeps the field at
 * a probe's lifted end, as the surface cache's probes do, samples it once, not once per test).
 * ga_memo: pa's gradient, for the tests that need it (vec4(0) before the first; the caller keeps
 * it while pa stays, gi_scene_gradients). */
bool gi_visible_between(vec3 pa, float da, vec3 pb, float db, float voxel, inout vec4 ga_memo)
{
  float shell = GI_HIT_VOXELS * voxel;
  float gap = length(pb - pa);
  if (gap < shell) {
    return true;
  }
  int obj;
  if (da + db - 2.0 * shell >= gap) {
    return true;           /* the two ends' empty balls, each less the hit shell, cover the
                            * segment: no sample on it can come within the shell of a surface,
                            * so the trace below would find nothing (bench/object_scaling.py:
                            * a default F12 among 1,000 spheres 65 -> 55 s, images the same
                            * but 0.2% of yard's pixels, by at most 1.5%) */
  }
  if (max(da, db) <= shell) {
    /* Both ends within half a voxel of a surface: no ray can tell. Two points on the two sides
     * of a wall thinner than a voxel see its field rise away from it in opposite directions;
     * two points in one concave corner see the same. */
    vec3 gb;
    gi_scene_gradients(pa, pb, voxel, ga_memo, gb);
    return dot(ga_memo.xyz, gb) > 0.0;
  }
  if (da < db) {
    vec3 tmp = pa;
    pa = pb;
    pb = tmp;
    float td = da;
    da = db;
    db = td;
  }
  vec3 d = pb - pa;
  float len = length(d);
  float stop = db <= shell + 0.25 * voxel ? len - GI_STOP_MARGIN * (shell + 0.25 * voxel - db) : len;
  if (stop <= 0.0) {
    return true;
  }
  float t;
  return !gi_trace_mesh(pa, d / len, 0.0, stop, t, obj);
}

bool gi_visible_from(vec3 pa, float da, vec3 b, vec3 nb, float voxel, inout vec4 ga_memo)
{
  vec3 pb = gi_lifted(b, nb, voxel);
  if (length(pb - pa) < max(GI_HIT_VOXELS * voxel, da - GI_HIT_VOXELS * voxel)) {
    return true;           /* before sampling b's end: the pairs closer than half a voxel (an
                            * anti-aliasing sample's neighbours, mostly) cost no field sample,
                            * nor does a pb inside a's empty ball less the hit shell (every point
                            * of the segment is farther than the shell from any surface, so
                            * the trace would find nothing: a surface-cache read tests each
                            * card texel around its hit this way; among 1,000 spheres, where
                            * that read is most hits' cost, the frame 0.94x) */
  }
  float h;
  int obj;
  return gi_visible_between(pa, da, pb, sdf_scene(pb, h, obj), voxel, ga_memo);
}

bool gi_visible_from(vec3 pa, float da, vec3 b, vec3 nb, float voxel)
{
  vec4 memo = vec4(0.0);
  return gi_visible_from(pa, da, b, nb, voxel, memo);
}

bool gi_visible(vec3 a, vec3 na, vec3 b, vec3 nb, float voxel)
{
  vec3 pa = gi_lifted(a, na, voxel);
  float h;
  int obj;
  return gi_visible_from(pa, sdf_scene(pa, h, obj), b, nb, voxel);
}
