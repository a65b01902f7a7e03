/* Lumen's ray (lecture 21, "Speed of Different Tracing Methods"; needs gi_trace_lib.glsl,
 * screen_trace_lib.glsl and screen_trace.py's SAMPLERS and PUSH): the screen first (HZB, at
 * most screen_steps cells; a hit reads screen_colour), then from where the depth buffer stops
 * vouching for the ray (t_free) the mesh SDFs, the global SDF and the sky (gi_radiance_from).
 * screen_steps 0: the SDFs from the origin.
 * kind: LUMEN_SKY (nothing hit before tmax), LUMEN_SCREEN, LUMEN_MESH (a hit before
 * GSDF_MESH_SPLIT), LUMEN_GLOBAL (after it). */
#define LUMEN_SKY 0
#define LUMEN_SCREEN 1
#define LUMEN_MESH 2
#define LUMEN_GLOBAL 3

mat4 screen_view_proj()
{
  return mat4(texelFetch(screen_camera, ivec2(0, 0), 0), texelFetch(screen_camera, ivec2(1, 0), 0),
              texelFetch(screen_camera, ivec2(2, 0), 0), texelFetch(screen_camera, ivec2(3, 0), 0));
}

vec3 lumen_radiance(vec3 o, vec3 dir, float tmax, out float hit_t, out int kind)
{
  float t_start = 0.0;
  if (screen_steps > 0) {
    float t_free;
    ivec2 hit_px;
    float ts = screen_trace(screen_view_proj(), screen_cam.xyz, o, dir, tmax, screen_steps,
                            screen_cam.w, t_free, hit_px);
    if (ts >= 0.0) {
      hit_t = ts;
      kind = LUMEN_SCREEN;
      return texelFetch(screen_colour, hit_px, 0).rgb;
    }
    t_start = t_free;
  }
  float w;
  vec3 L = gi_radiance_from(o, dir, t_start, tmax, hit_t, w);
  kind = hit_t >= tmax ? LUMEN_SKY : (hit_t < GSDF_MESH_SPLIT ? LUMEN_MESH : LUMEN_GLOBAL);
  return L;
}
