#include "sdf_lib.glsl"
#include "sky_lib.glsl"
#include "camera_lib.glsl"
#include "light_lib.glsl"
#include "gbuffer_shading_lib.glsl"
/* Lumen GI direct light per pixel from the G-buffer (needs sdf_lib.glsl, light_lib.glsl,
 * sky_lib.glsl, camera_lib.glsl).
 *
 * Inputs: gbuf_position, gbuf_normal, gbuf_albedo, gbuf_emission (gbuffer.glsl), lights
 * (RGBA32F, 4 texels per light row, operators/lights.py; a sun taken out of the world's map is
 * one of them), sky_maps (the world), push constants light_count, cam_pos (world), sky_cones
 * (number of sky occlusion cones), inv_view_proj (camera rays for the background),
 * sample_plan = light_samples + 256 * first + 65536 * take + 16777216 * mode
 * + 268435456 * transparent (Film > Transparent: the background rgba 0) + 536870912 * shading
 * normals packed (a drawn mesh has a normal map: gbuffer_shading_lib.glsl): samples per light,
 * and the part of them and of the sky cones this dispatch evaluates (first 0, take light_samples:
 * all; one int keeps the push constants within 128 bytes); mode 1 also stores the one-sample
 * lights' (suns, lights without radius: light_single) E in `single`, mode 2 reads it from there
 * instead of evaluating them again (the viewport's later parts: every part of such a light is
 * the whole light, direct_light.Progressive). Mode 3, the viewport: each pixel its own part,
 * from parts_in (the parts its running mean holds: direct_restart.comp.glsl): part c takes
 * `take` samples from c * take on, stores the one-sample lights' E at c = 0 and reads it after;
 * a pixel with `first` (there: the parts of a whole mean) or more writes nothing.
 * Outputs (RGBA32F):
 *   direct_out:   Cycles' "Diffuse Direct" convention: E / pi, E the direct irradiance from the
 *                 lights and the sky (a Lambert BSDF without its albedo); 0 on the background
 *   combined_out: albedo * direct + emission; the world's radiance on the background
 * Lights, shadows and sky visibility: light_lib.glsl. sky_cones = 0 leaves the sky out (the GI
 * passes add it from their rays' misses instead).
 *
 * Sky light: E_sky(n) unoccluded is exact for the map (sky_irradiance: E(n) integrated over all
 * its pixels); the SDF cones say how much of it is blocked, each cone weighted by the radiance
 * the sky has in its direction (sky_ray), so a bright zenith blocked by a roof darkens more than
 * the same cone toward a dark horizon.
 */
vec3 sky_light(vec3 p, vec3 n, vec3 ns, int cones, int first, int take)
{
  vec3 E = sky_irradiance(ns);        /* the shading normal's; the cones' visibility n's */
  if (!any(greaterThan(E, vec3(0.0)))) {
    return vec3(0.0);
  }
  vec3 u, v;
  sky_cone_basis(n, u, v);
  vec3 seen = vec3(0.0);
  vec3 all_ = vec3(0.0);
  float voxel;
  int nearest;
  sdf_scene(p, voxel, nearest);
  /* every cone's radiance (texture reads only), then the visibility of `take` of them from
   * `first` on, scaled by cones / take: parts over consecutive redraws that cover every cone once
   * average to the whole (the viewport's progressive direct light, direct_light.py) */
  int n_take = clamp(take, 1, cones);
  for (int i = 0; i < cones; i++) {
    all_ += sky_ray(sky_cone_dir(i, cones, n, u, v)) + 1e-6;
  }
  for (int j = 0; j < n_take; j++) {
    int i = (first + j) % cones;
    vec3 dir = sky_cone_dir(i, cones, n, u, v);
    vec3 L = sky_ray(dir) + 1e-6;
    /* An open plane must not occlude its own sky: its field along dir is t sin(e) (e the
     * cone's elevation), so with the half-voxel thin-wall rule measured from where that field
     * leaves the receiver's shell (t_shell) and k >= 1 / sin(e) (the cone no wider than its
     * elevation) the plane reads k sin(e) >= 1, and a convex surface more. With k = 2 for every
     * cone from the surface a sphere under a uniform sky lost 20% of it. */
    float elev_sin = max(dot(dir, n), 0.05);
    seen += L * cone_visibility_shell(p, n, dir, SKY_CONE_REACH, sky_cone_k(dir, n),
                                      THIN_VOXELS * voxel / elev_sin);
  }
  return E * seen * (float(cones) / float(n_take)) / all_;
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(direct_out);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  int light_samples = sample_plan % 256;
  int sample_first = (sample_plan / 256) % 256;
  int sample_take = (sample_plan / 65536) % 256;
  int mode = (sample_plan / 16777216) % 16;
  if (mode == 3) {
    int c = int(texelFetch(parts_in, px, 0).r + 0.5);
    if (c >= sample_first) {
      return;                        /* its mean is whole */
    }
    sample_first = c * sample_take;
    mode = c == 0 ? 1 : 2;
  }
  vec4 pos = texelFetch(gbuf_position, px, 0);
  if (pos.w < 0.5) {
    imageStore(direct_out, px, vec4(0.0, 0.0, 0.0, 1.0));
    vec3 ro, rd;
    camera_ray(px, size, ro, rd);
    /* Film > Transparent: nothing (rgba 0) where no surface is; a holdout (position w 0.25,
     * gbuffer.glsl): nothing either way */
    imageStore(combined_out, px, (sample_plan / 268435456) % 2 == 1 || pos.w > 0.125 ?
                                     vec4(0.0) : vec4(sky_background(rd), 1.0));
    return;
  }
  vec3 p = pos.xyz;
  vec3 n = normalize(texelFetch(gbuf_normal, px, 0).xyz);
  vec3 ns = gbuf_shading_normal(px, n, (sample_plan / 536870912) % 2 == 1);
  if (dot(n, cam_pos - p) < 0.0) {
    n = -n; /* back face: shade the side the camera sees, as Cycles does */
    ns = -ns;
  }
  vec3 E = vec3(0.0);
  vec3 E_single = vec3(0.0);
  for (int i = 0; i < light_count; i++) {
    bool single = mode > 0 && light_single(i);
    if (single && mode == 2) {
      continue;
    }
    vec3 e = light_irradiance_part(i, p, n, ns, light_samples, light_rotation(px),
                                   sample_first, sample_take);
    E += e;
    E_single += single ? e : vec3(0.0);
  }
  if (mode == 1) {
    imageStore(single, px, vec4(E_single, 1.0));
  }
  else if (mode == 2) {
    E += imageLoad(single, px).rgb;
  }
  if (sky_cones > 0) {
    E += sky_light(p, n, ns, sky_cones, sample_first, sample_take);
  }
  vec3 direct = E / PI;
  vec3 albedo = texelFetch(gbuf_albedo, px, 0).rgb;
  vec3 emission = texelFetch(gbuf_emission, px, 0).rgb;
  imageStore(direct_out, px, vec4(direct, 1.0));
  imageStore(combined_out, px, vec4(albedo * direct + emission, 1.0));
}
