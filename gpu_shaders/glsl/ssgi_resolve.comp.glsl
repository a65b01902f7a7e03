#include "gbuffer_lib.glsl"
#include "mip_lib.glsl"
/* SSGI resolve (ssgi.py; lecture 21, "Ray Reuse among Neighbor Pixels", "Cone Tracing with
 * Mipmap Filtering"): per pixel x (normal n), the rays of every pixel q in a (2 reuse + 1)^2
 * window that lies on x's surface (normals within ~37 degrees, q within 2% of x's distance of
 * x's tangent plane) are taken as x's own: a hit of q at Y is the direction Y - x with q's hit
 * (visibility assumed the same between neighbours, as the lecture says), a miss is q's direction
 * bringing nothing. Each sample is weighted by x's cosine over q's pdf, cos_x / cos_q (the
 * lecture's ratio estimator; q's own rays weigh 1), and
 *     E = pi * sum(w L) / sum(w).
 * L at a hit: the colour pyramid (scene colour: last frame's lit image, premultiplied by
 * coverage) at Y's pixel, at the mip whose texels match the cone a sample stands for: a cone of
 * half-angle acos(1 - 1 / samples) (cone_tan = its tangent) around Y - x, its radius at Y
 * projected to pixels; trilinear between the two nearest levels.
 * Inputs: gbuf_position, gbuf_normal, hits (ssgi_trace), colour (atlas); push view_proj, cam_pos,
 * rays, reuse, cone_tan.
 * Output out_image: E (irradiance, rgb), w = 1 on surfaces, 0 on the background.
 */
#define PI 3.14159265358979

vec4 colour_level(int level, vec2 pix, ivec2 base)
{
  ivec2 off, size;
  mip_rect(level, base, off, size);
  vec2 f = pix / float(1 << level) - 0.5;
  ivec2 i0 = ivec2(floor(f));
  vec2 t = f - vec2(i0);
  ivec2 a = clamp(i0, ivec2(0), size - 1);
  ivec2 b = clamp(i0 + 1, ivec2(0), size - 1);
  vec4 c00 = texelFetch(colour, off + ivec2(a.x, a.y), 0);
  vec4 c10 = texelFetch(colour, off + ivec2(b.x, a.y), 0);
  vec4 c01 = texelFetch(colour, off + ivec2(a.x, b.y), 0);
  vec4 c11 = texelFetch(colour, off + ivec2(b.x, b.y), 0);
  return mix(mix(c00, c10, t.x), mix(c01, c11, t.x), t.y);
}

/* Cone-filtered radiance around pixel position pix (level-0 pixels) at mip `lod`. */
vec3 colour_cone(vec2 pix, float lod, ivec2 base)
{
  int top = mip_count(base) - 1;
  lod = clamp(lod, 0.0, float(top));
  int l0 = int(floor(lod));
  int l1 = min(l0 + 1, top);
  vec4 c = mix(colour_level(l0, pix, base), colour_level(l1, pix, base), lod - float(l0));
  return c.a > 1e-6 ? c.rgb / c.a : vec3(0.0);
}

vec3 project_pixel(vec3 y, vec2 size)
{
  vec4 h = view_proj * vec4(y, 1.0);
  return vec3((h.xy / h.w * 0.5 + 0.5) * size, h.w);
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = textureSize(gbuf_position, 0);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  float dist = distance(p, cam_pos);
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  for (int dy = -reuse; dy <= reuse; dy++) {
    for (int dx = -reuse; dx <= reuse; dx++) {
      ivec2 q = px + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) {
        continue;
      }
      vec3 pq, nq;
      if (!gbuf_surface(q, cam_pos, pq, nq)) {
        continue;
      }
      if (dot(nq, n) < 0.8 || abs(dot(n, pq - p)) > 0.02 * dist) {
        continue;
      }
      for (int k = 0; k < rays; k++) {
        vec4 h = texelFetch(hits, ivec2(q.x * rays + k, q.y), 0);
        if (h.w < -2.5) {
          continue;
        }
        float pdf_q = max(dot(nq, h.xyz), 1e-3);
        vec3 dir = h.xyz;
        vec3 L = vec3(0.0);
        if (h.w >= 0.0) {
          vec3 y = pq + h.xyz * h.w;
          vec3 to = y - p;
          float r = length(to);
          if (r < 1e-6) {
            continue;
          }
          dir = to / r;
          vec3 c = project_pixel(y, vec2(size));
          /* the cone's radius at y, projected: a world offset across the view ray at y */
          vec3 view = normalize(y - cam_pos);
          vec3 across = normalize(cross(view, abs(view.z) < 0.9 ? vec3(0.0, 0.0, 1.0) :
                                                                  vec3(1.0, 0.0, 0.0)));
          vec3 c2 = project_pixel(y + across * (r * cone_tan), vec2(size));
          float radius_px = length(c2.xy - c.xy);
          L = colour_cone(c.xy, log2(max(2.0 * radius_px, 1.0)), size);
        }
        float w = max(dot(n, dir), 0.0) / pdf_q;
        sum += w * L;
        wsum += w;
      }
    }
  }
  vec3 E = wsum > 0.0 ? PI * sum / wsum : vec3(0.0);
  imageStore(out_image, px, vec4(E, 1.0));
}
