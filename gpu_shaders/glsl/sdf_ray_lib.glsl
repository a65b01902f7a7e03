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

/* World voxel edge of object obj (the unit of ray offsets off its surface). */
float gi_object_voxel(int obj)
{
  return sdf_object_texel(obj, 4).w * sdf_object_texel(obj, 7).w;
}

/* Whether light gathered at b may be used at a (nearby points on surfaces with normals na, nb):
 * both lifted LIFT_VOXELS off their surfaces, the segment between them must not meet a surface
 * (gi_trace_mesh, the thin-wall rule included). Interpolating probes across a wall is how light
 * leaks into a closed room that stands on a lit floor. */
#define GI_LIFT_VOXELS 1.5
bool gi_visible(vec3 a, vec3 na, vec3 b, vec3 nb, float voxel)
{
  vec3 pa = a + na * (GI_LIFT_VOXELS * voxel);
  vec3 pb = b + nb * (GI_LIFT_VOXELS * voxel);
  vec3 d = pb - pa;
  float len = length(d);
  if (len < 0.5 * voxel) {
    return true;
  }
  float t;
  int obj;
  return !gi_trace_mesh(pa, d / len, 0.0, len, t, obj);
}
