#include "sdf_lib.glsl"
#include "global_sdf_lib.glsl"
/* Lumen GI: trace_hybrid, a ray through the mesh SDFs near its origin and the global SDF beyond
 * (split from global_sdf_lib.glsl, which needs no mesh SDFs). */
/* Sphere trace from origin along unit dir up to tmax: the mesh SDFs (sdf_scene) while
 * t < GSDF_MESH_SPLIT, the global SDF beyond. Stepping as sdf_trace.comp.glsl: hit when
 * d <= 0.05 voxel, advance by max(d, 0.1 voxel), the voxel being the nearest object's (mesh part)
 * or the sampled level's (global part). Leaving the coarsest clipmap is a miss. Returns the hit t
 * or -1; steps: samples taken; global_steps: of those, global SDF samples. */
float trace_hybrid(vec3 origin, vec3 dir, float tmax, int max_steps, out int steps, out int global_steps)
{
  float t = 0.0;
  steps = 0;
  global_steps = 0;
  while (steps < max_steps && t <= tmax) {
    vec3 p = origin + t * dir;
    float d, h;
    steps++;
    if (t < GSDF_MESH_SPLIT) {
      int nearest;
      d = sdf_scene(p, h, nearest);
      if (d <= 0.05 * h) {
        return t;
      }
    }
    else {
      int level;
      global_steps++;
      d = global_sdf_sample(p, level, h);
      if (level < 0) {
        return -1.0;
      }
      if (d <= 0.05 * h) {
        return t;
      }
    }
    t += max(d, 0.1 * h);
  }
  return -1.0;
}

float trace_hybrid(vec3 origin, vec3 dir, float tmax)
{
  int steps, global_steps;
  return trace_hybrid(origin, dir, tmax, 512, steps, global_steps);
}
