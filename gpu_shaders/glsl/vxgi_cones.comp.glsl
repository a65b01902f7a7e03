#include "global_sdf_lib.glsl"
#include "sky_lib.glsl"
#include "gbuffer_lib.glsl"
#include "sampling_lib.glsl"
#include "voxel_lighting_lib.glsl"
/* VXGI: voxel cone tracing over the voxel lighting clipmaps (lecture 21, "Shading with Cone
 * Tracing", "Accumulate Voxel Radiance and Opacity along the Path"). Per G-buffer pixel, `cones`
 * cones of half-angle h in the normal's hemisphere: one along the normal, the rest on a ring at
 * polar angle (h + 90 deg) / 2 (rotated per frame). A cone marches front to back:
 *   radius    r = t sin h (the sphere inscribed in the cone: a ring cone whose edge grazes the
 *             pixel's own plane does not see that plane)
 *   opacity   saturate(1 - d / r), d the global SDF at the sample (the finest informative level;
 *             0 where even that is saturated at its band: no surface known within it): the
 *             share of the cone's cross-section a surface covers; corrected for the step,
 *             1 - (1 - occ)^(dt / r), so the opacity of a wall does not depend on how many
 *             samples fall near it
 *   radiance  vl_sample of the clipmap level whose voxel is at least r (trilinear over 8 voxels
 *             spans 2 voxels: the cone's diameter), the 3 faces along the cone weighted by dir^2;
 *             where no face of that level serves the sample, the finer levels'; where none
 *             does, the opacity waits for the next served sample's radiance (the surface the
 *             cone closes in on: a face's short ray reaches 1.5 voxels, a sample with d < r
 *             can be 2 voxels from the wall; 22-31% of the cones' opacity met no face on
 *             cornell and window before this), or the last radiance met if none comes
 *   C += (1 - A) a L,  A += (1 - A) a;  step max(step r, d - r) (no surface can come nearer
 *             than r within it); stop at A >= 0.99, t_max or outside the coarsest clipmap
 *   sky       C += (1 - A) sky_ray(axis) for what passes through
 * E = sum_i w_i C_i, w = pi sin^2 h for the centre cone and pi cos^2 h / (cones - 1) for each
 * ring cone (the cosine-weighted solid angles of the cap and the ring: they sum to pi, so a
 * uniform radiance L gives E = pi L); one cone: w = pi.
 * Inputs: gbuf_position, gbuf_normal; cam_tmax (camera, t_max), cone (sin h, cos h, step,
 * start offset in level-0 voxels), counts (cones, frame).
 * Output out_image: E.rgb, w = mean opacity A of the cones (the VXGI_OCCLUSION view); -1 on the
 * background.
 */
#define PI 3.14159265358979
#define VX_MAX_STEPS 48

/* The level a sample at world p of cone radius r reads: the finest holding p whose voxel is at
 * least r (the coarsest holding p when r is larger still); -1 outside every level. */
int vx_level(vec3 p, float r)
{
  int n = textureSize(gsdf_level0, 0).x;
  int found = -1;
  for (int k = GSDF_LEVELS - 1; k >= 0; k--) {
    vec4 info = gsdf_origin(k);
    vec3 g = p / info.w - 0.5 - info.xyz;
    bool inside = all(greaterThanEqual(g, vec3(0.0))) && all(lessThanEqual(g, vec3(float(n - 1))));
    if (!inside) {
      break;                      /* the finer levels are inside this one */
    }
    if (info.w >= r || found < 0) {
      found = k;
    }
  }
  return found;
}

vec3 vx_cone(vec3 o, vec3 dir, float sin_h, float t0, float tmax, float step_scale,
             out float alpha)
{
  vec3 c = vec3(0.0);
  float pending = 0.0;            /* opacity met where no voxel face served the sample */
  vec3 last = vec3(0.0);
  bool seen = false;
  float a = 0.0;
  float t = t0;
  for (int i = 0; i < VX_MAX_STEPS && t < tmax && a < 0.99; i++) {
    vec3 p = o + t * dir;
    float r = max(t * sin_h, 1e-4);
    int level = vx_level(p, r);
    if (level < 0) {
      break;                      /* left the coarsest clipmap: the sky */
    }
    int sl;
    float sv;
    float d = global_sdf_sample(p, sl, sv);
    float dt = max(step_scale * r, d - r);
    /* a value saturated at its level's band says only "no surface within the band": a cone
     * wider than that sees nothing there (else an open sky reads as occluded far away) */
    bool empty = d >= 0.999 * gsdf.band.x * sv;
    float occ = empty ? 0.0 : clamp(1.0 - d / r, 0.0, 1.0);
    if (occ > 0.0) {
      occ = 1.0 - pow(1.0 - min(occ, 0.999), dt / r);
      vec3 L;
      bool ok = false;
      for (int k = level; k >= 0 && !ok; k--) {
        ok = vl_sample(k, p, dir, vec3(0.0), L);
      }
      if (ok) {
        c += pending * L;         /* the surface the cone was closing in on */
        pending = 0.0;
        last = L;
        seen = true;
        c += (1.0 - a) * occ * L;
      }
      else {
        pending += (1.0 - a) * occ;
      }
      a += (1.0 - a) * occ;
    }
    t += dt;
  }
  c += pending * last;            /* nothing served after it: the last light met (0: none) */
  c += (1.0 - a) * sky_ray(dir);
  alpha = a;
  return c;
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 cam = cam_tmax.xyz;
  vec3 p, n;
  if (!gbuf_surface(px, cam, p, n)) {
    imageStore(out_image, px, vec4(0.0, 0.0, 0.0, -1.0));
    return;
  }
  int cones = max(counts.x, 1);
  float sin_h = cone.x, cos_h = cone.y;
  float v0 = gsdf_origin(0).w;
  /* start off the surface: the start offset in level-0 voxels plus the thin-wall margin (a thin
   * wall's field stays that far above zero on it) */
  vec3 o = p + n * (cone.w * v0 + gsdf.band.y);
  float t0 = 0.5 * v0;
  mat3 frame = tangent_frame(n);
  int ring = cones - 1;
  float polar = 0.5 * (asin(clamp(sin_h, 0.0, 1.0)) + 0.5 * PI);
  float rot = fract(float(counts.y) * 0.6180339887) * 2.0 * PI / float(max(ring, 1));
  vec3 e = vec3(0.0);
  float occl = 0.0;
  for (int i = 0; i < cones; i++) {
    vec3 dir;
    float w;
    if (i == 0) {
      dir = n;
      w = ring > 0 ? PI * sin_h * sin_h : PI;
    }
    else {
      float phi = rot + 2.0 * PI * float(i - 1) / float(ring);
      dir = frame * vec3(sin(polar) * cos(phi), sin(polar) * sin(phi), cos(polar));
      w = PI * cos_h * cos_h / float(ring);
    }
    float a;
    e += w * vx_cone(o, dir, sin_h, t0, cam_tmax.w, cone.z, a);
    occl += a;
  }
  imageStore(out_image, px, vec4(e, occl / float(cones)));
}
