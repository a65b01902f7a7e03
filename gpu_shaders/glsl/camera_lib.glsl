/* Primary rays: one per pixel centre, from the inverse view-projection matrix (push constant
 * `inv_view_proj` of the including shader). Shared by every pass that traces camera rays. */
void camera_ray(ivec2 px, ivec2 size, out vec3 ro, out vec3 rd)
{
  vec2 ndc = (vec2(px) + 0.5) / vec2(size) * 2.0 - 1.0;
  vec4 a = inv_view_proj * vec4(ndc, -1.0, 1.0);
  vec4 b = inv_view_proj * vec4(ndc, 1.0, 1.0);
  ro = a.xyz / a.w;
  rd = normalize(b.xyz / b.w - ro);
}
