/* Lumen GI: reading the G-buffer in compute passes (samplers gbuf_position, gbuf_normal).
 * gbuf_surface: the surface at pixel px, world position p and unit normal n turned to face the
 * camera at cam (a back face shades the side the camera sees, as Cycles does); false on the
 * background. */
bool gbuf_surface(ivec2 px, vec3 cam, out vec3 p, out vec3 n)
{
  vec4 pos = texelFetch(gbuf_position, px, 0);
  p = pos.xyz;
  n = vec3(0.0, 0.0, 1.0);
  if (pos.w < 0.5) {
    return false;
  }
  n = normalize(texelFetch(gbuf_normal, px, 0).xyz);
  if (dot(n, cam - p) < 0.0) {
    n = -n;
  }
  return true;
}
