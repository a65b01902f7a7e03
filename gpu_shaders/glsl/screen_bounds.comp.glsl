/* Lumen's first trace (screen_trace.py): per pixel the neighbours' bound, the window depth (as
 * the HZB holds it) in front of which every point of the pixel's column is in front of each of
 * its 4 neighbours' planes (on the camera's side); 2.0 for none (no neighbour shows a surface off
 * the pixel's plane: normals more than BOUNDS_EDGE_COS apart, or its point more than
 * BOUNDS_EDGE_GAP off the plane); 0 on the background.
 * Why: the depth buffer does not show the sub-pixel rim of a neighbour's surface (a wall's side
 * seen nearly edge-on), and Lumen's walk (screen_trace_lib.glsl) vouches for a pixel's empty
 * space only where the ray's segment is wholly in front of this bound. Computed once per frame
 * here and not per ray step in the walk: the four plane tests there (eight G-buffer fetches in a
 * loop) made the probe trace 5-16% slower, even where no ray ran them (llvmpipe;
 * bench/f12_ab.py, the README's issue 12 notes).
 * How: a plane's NDC depth is affine in NDC x, y (its equation times inverse(view_proj) is its
 * clip-space plane), so over the pixel its least is at a corner. Below -1 (it crosses the view
 * ray between the camera and the near plane) nothing is vouched for (0); above 1 (beyond the far
 * plane, or behind the camera) it sets no bound. A neighbour on the pixel's own plane sets none:
 * the walk asks for a voxel in front of that plane anyway.
 * Inputs: gbuf_position, gbuf_normal; push view_proj. Output: bounds (R32F, the image's size).
 */
#define BOUNDS_TILE 8             /* screen_trace.py's BOUNDS pass: 8 x 8 work groups */
#define BOUNDS_SIDE (BOUNDS_TILE + 2)
#define BOUNDS_EDGE_COS 0.9998    /* ~1.1 degrees */
#define BOUNDS_EDGE_GAP 0.001     /* metres */
/* Per tile texel: the point, the unit normal (0: nothing shown, or off the image) and the plane
 * in clip space (nothing after a shared declaration's ';': compute.hoist_shared). */
shared vec3 s_point[BOUNDS_SIDE * BOUNDS_SIDE];
shared vec3 s_normal[BOUNDS_SIDE * BOUNDS_SIDE];
shared vec4 s_clip[BOUNDS_SIDE * BOUNDS_SIDE];

/* Whether tile texel k's neighbour j shows a surface off k's plane (both show one). */
bool off_plane(int k, int j)
{
  vec3 a = s_normal[k], b = s_normal[j];
  return dot(b, b) > 0.5 && (abs(dot(a, b)) < BOUNDS_EDGE_COS
                             || abs(dot(s_point[j] - s_point[k], a)) > BOUNDS_EDGE_GAP);
}

/* The bound of pixel px (tile texel k, which shows a surface; the header). */
float neighbour_bound(ivec2 px, int k, vec2 size)
{
  vec2 half_px = 1.0 / size;                         /* half a pixel in NDC */
  vec2 c = (vec2(px) + 0.5) * 2.0 * half_px - 1.0;   /* the pixel's centre in NDC */
  float bound = 2.0;
  for (int e = 0; e < 4; e++) {
    int j = k + (e == 0 ? 1 : (e == 1 ? -1 : (e == 2 ? BOUNDS_SIDE : -BOUNDS_SIDE)));
    /* every neighbour computed, branch-free: on llvmpipe skipping the coplanar ones was slower */
    bool off = off_plane(k, j);
    vec4 pc = s_clip[j];                             /* a x + b y + c z + d = 0 in NDC */
    /* seen edge-on from the camera: as if below -1 (0) */
    float least = abs(pc.z) < 1e-30 ? -2.0
                  : -(dot(pc.xy, c) + pc.w) / pc.z - dot(abs(pc.xy / pc.z), half_px);
    float b = least < -1.0 ? 0.0 : (least <= 1.0 ? least * 0.5 + 0.5 : 2.0);
    bound = min(bound, off ? b : 2.0);
  }
  return bound;
}

/* One work group (8 x 8 pixels) loads the points, normals and clip-space planes of its pixels
 * and their one-pixel border (10 x 10) once into shared memory: each pixel's four neighbours
 * read them. */
void main()
{
  ivec2 size = textureSize(gbuf_position, 0);
  ivec2 corner = ivec2(gl_WorkGroupID.xy) * BOUNDS_TILE - 1;
  mat4 to_clip = inverse(view_proj);                 /* world planes to clip space */
  for (int k = int(gl_LocalInvocationIndex); k < BOUNDS_SIDE * BOUNDS_SIDE;
       k += BOUNDS_TILE * BOUNDS_TILE) {
    ivec2 q = corner + ivec2(k % BOUNDS_SIDE, k / BOUNDS_SIDE);
    bool inside = all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, size));
    vec4 pos = inside ? texelFetch(gbuf_position, q, 0) : vec4(0.0);
    vec3 n = pos.w >= 0.5 ? normalize(texelFetch(gbuf_normal, q, 0).xyz) : vec3(0.0);
    s_point[k] = pos.xyz;
    s_normal[k] = n;
    s_clip[k] = vec4(n, -dot(n, pos.xyz)) * to_clip;
  }
  barrier();
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  int k = (int(gl_LocalInvocationID.y) + 1) * BOUNDS_SIDE + int(gl_LocalInvocationID.x) + 1;
  float bound = dot(s_normal[k], s_normal[k]) > 0.5 ? neighbour_bound(px, k, vec2(size)) : 0.0;
  imageStore(bounds, px, vec4(bound, 0.0, 0.0, 0.0));
}
