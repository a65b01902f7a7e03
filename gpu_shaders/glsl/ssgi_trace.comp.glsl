/* SSGI trace (ssgi.py; lecture 21, "Radiance Sampling in Screen Space", "Hierachical Tracing"):
 * `rays` rays per G-buffer pixel in the cosine hemisphere of its normal (stratified Hammersley
 * points, rotated per pixel and frame), each walked through the HZB (hzb, mip_lib.glsl: MIN of
 * window depths) as a straight line in (pixel x, pixel y, window depth):
 *   a segment whose depth stays in front of its cell's MIN skips the cell and climbs a level;
 *   otherwise it descends; at level 0 the segment inside the pixel is tested against the
 *   pixel's surface plane (G-buffer position and normal): it hits where it crosses the plane
 *   from in front, or if it entered the pixel behind the plane by at most `thickness` metres
 *   (surfaces are assumed that thick: the depth buffer has no back faces); past that it walks
 *   on behind the surface. (The plane and not the pixel's centre depth: at a grazing angle one
 *   pixel spans a long stretch of its surface.)
 * At most max_steps cells are visited (the lecture: 50). The world ray is clipped to the near and
 * far planes, its screen line to the image.
 * Inputs: gbuf_position, gbuf_normal, hzb; push view_proj, cam_tmax (camera position xyz, w the
 * world length of a ray), counts (rays per pixel, frame, max_steps), thickness (packed so: Blender
 * counts scalars after a vec3 so that the plain list passed 128 bytes).
 * Output out_image [width x rays, height]: ray k of pixel p at (p.x * rays + k, p.y) =
 *   (world direction xyz, w): w >= 0 hit at that distance; -1 left the screen (or reached t_max /
 *   the far plane); -2 out of steps; -3 no surface at the pixel.
 */
#define SSGI_LEFT -1.0
#define SSGI_STEPS -2.0
#define SSGI_NONE -3.0

vec3 ssgi_screen(vec4 h, vec2 size)
{
  vec3 ndc = h.xyz / h.w;
  return vec3((ndc.xy * 0.5 + 0.5) * size, ndc.z * 0.5 + 0.5);
}

void main()
{
  vec3 cam_pos = cam_tmax.xyz;
  float t_max = cam_tmax.w;
  int rays = counts.x;
  int frame = counts.y;
  int max_steps = counts.z;
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 out_size = imageSize(out_image);
  if (gid.x >= out_size.x || gid.y >= out_size.y) {
    return;
  }
  ivec2 px = ivec2(gid.x / rays, gid.y);
  int k = gid.x - px.x * rays;
  ivec2 size = textureSize(gbuf_position, 0);
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, gid, vec4(0.0, 0.0, 1.0, SSGI_NONE));
    return;
  }
  uint seed = pcg_hash(uint(px.x) + uint(px.y) * 65536u + uint(frame) * 40503u);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 dir = cosine_hemisphere(fract(hammersley(uint(k), uint(rays)) + rot), n);

  /* start a hair off the surface (relative to its distance: the depth's precision is too) */
  vec3 o = p + n * (1e-4 * distance(p, cam_pos) + 1e-4);
  vec4 h0 = view_proj * vec4(o, 1.0);
  vec4 h1 = view_proj * vec4(o + dir * t_max, 1.0);
  /* clip the world segment to the near (z + w >= 0) and far (w - z >= 0) planes */
  float frac = 1.0;
  float a0 = h0.z + h0.w, a1 = h1.z + h1.w;
  if (a1 < 0.0) {
    frac = min(frac, 0.999 * a0 / (a0 - a1));
  }
  float b0 = h0.w - h0.z, b1 = h1.w - h1.z;
  if (b1 < 0.0) {
    frac = min(frac, 0.999 * b0 / (b0 - b1));
  }
  float len = t_max * frac;
  h1 = mix(h0, h1, frac);
  vec3 s0 = ssgi_screen(h0, vec2(size));
  vec3 s1 = ssgi_screen(h1, vec2(size));
  vec3 d = s1 - s0;
  float w0 = h0.w, w1 = h1.w;

  /* where the screen line leaves the image */
  float s_end = 1.0;
  if (d.x > 0.0) {
    s_end = min(s_end, (float(size.x) - s0.x) / d.x);
  }
  else if (d.x < 0.0) {
    s_end = min(s_end, -s0.x / d.x);
  }
  if (d.y > 0.0) {
    s_end = min(s_end, (float(size.y) - s0.y) / d.y);
  }
  else if (d.y < 0.0) {
    s_end = min(s_end, -s0.y / d.y);
  }
  float pix_len = length(d.xy);
  float eps = 1e-3 / max(pix_len, 1e-6);
  vec2 inv_d = vec2(d.x != 0.0 ? 1.0 / d.x : 1e30, d.y != 0.0 ? 1.0 / d.y : 1e30);

  int top = mip_count(size) - 1;
  int level = 0;
  float result = SSGI_STEPS;
  float s = 0.0;
  bool first = true;        /* the start pixel: leave it before testing anything */
  for (int i = 0; i < max_steps; i++) {
    if (s >= s_end) {
      result = SSGI_LEFT;
      break;
    }
    vec3 P = s0 + d * s;
    ivec2 cell = ivec2(floor(clamp(P.xy, vec2(0.0), vec2(size) - 1e-3))) >> level;
    float cs = float(1 << level);
    vec2 lo = vec2(cell) * cs;
    vec2 hi = lo + cs;
    float sx = d.x > 0.0 ? (hi.x - s0.x) * inv_d.x : (d.x < 0.0 ? (lo.x - s0.x) * inv_d.x : 1e30);
    float sy = d.y > 0.0 ? (hi.y - s0.y) * inv_d.y : (d.y < 0.0 ? (lo.y - s0.y) * inv_d.y : 1e30);
    float s_exit = min(min(sx, sy), s_end);
    if (first) {
      first = false;
      s = s_exit + eps;
      continue;
    }
    float za = s0.z + d.z * s;
    float zb = s0.z + d.z * s_exit;
    ivec2 off, lsize;
    mip_rect(level, size, off, lsize);
    float zmin = texelFetch(hzb, off + cell, 0).x;
    if (max(za, zb) < zmin) {
      s = s_exit + eps;
      level = min(level + 1, top);
      continue;
    }
    if (level > 0) {
      level--;
      continue;
    }
    /* level 0: the pixel's surface plane, distances positive on the camera's side */
    vec3 ps, ns;
    if (gbuf_surface(cell, cam_pos, ps, ns)) {
      float ta = len * (s * w0 / ((1.0 - s) * w1 + s * w0));
      float tb = len * (s_exit * w0 / ((1.0 - s_exit) * w1 + s_exit * w0));
      float da = dot(o + dir * ta - ps, ns);
      float db = dot(o + dir * tb - ps, ns);
      if (da >= 0.0 && db < 0.0) {          /* crosses the plane from in front */
        result = ta + (tb - ta) * da / (da - db);
        break;
      }
      if (da < 0.0 && da >= -thickness) {   /* entered the pixel behind it, within the thickness */
        result = ta;
        break;
      }
    }
    s = s_exit + eps;
  }
  if (result == SSGI_STEPS && s >= s_end) {
    result = SSGI_LEFT;
  }
  imageStore(out_image, gid, vec4(dir, result));
}
