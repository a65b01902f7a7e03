/* Lumen GI: screen-probe interpolation weights ("Detect Non-Interpolatable Cases").
 * numpy twin: gpu_shaders/probe_math.py (probe_corner_weights).
 *
 * vec4 probe_corner_weights(vec2 bilinear, vec3 p00, vec3 p10, vec3 p01, vec3 p11,
 *                           vec4 corner_valid, vec4 scene_plane, float scene_depth,
 *                           out float lighting_valid)
 * Inputs:
 *   bilinear      the pixel's fractional position between the 4 surrounding probes, in [0,1]^2
 *   p00..p11      the probes' world positions (corner order 00, 10, 01, 11 = x then y)
 *   corner_valid  1 for a probe that exists / was traced, 0 for none (> 0.5 counts as valid)
 *   scene_plane   the pixel's plane: xyz = unit normal n, w = dot(n, pixel world position)
 *   scene_depth   the pixel's view depth (plane distances are taken relative to it)
 * Per corner: plane distance |dot(vec4(P, -1), scene_plane)|, relative = distance / scene_depth,
 * depth weight exp2(-10000 relative^2) (so 1 % of the depth off the plane: 0.5, 5 %: 2^-25),
 * 0 for an invalid corner. Weights (order 00, 10, 01, 11) = bilinear weights * depth weights, then
 *   W /= max(dot(W, 1), PROBE_WEIGHT_EPS);  lighting_valid = dot(W, 1) < 1 - EPS ? 0 : 1
 * exactly as the lecture. Returned: the normalised W. With EPS = 0.01 the normalised sum is 1 when
 * the raw sum s >= EPS and s / EPS below, so lighting_valid = 0 exactly when s < EPS * (1 - EPS)
 * = 0.0099 (the pixel then needs its own fallback, e.g. a per-pixel trace); between 0.0099 and
 * 0.01 it is 1 with weights summing to >= 0.99.
 */
#ifndef LUMEN_PROBE_INTERP_LIB
#define LUMEN_PROBE_INTERP_LIB

#define PROBE_WEIGHT_EPS 0.01
#define PROBE_PLANE_SHARPNESS 10000.0

vec4 probe_corner_weights(vec2 bilinear, vec3 p00, vec3 p10, vec3 p01, vec3 p11,
                          vec4 corner_valid, vec4 scene_plane, float scene_depth,
                          out float lighting_valid)
{
  vec4 w_bilinear = vec4((1.0 - bilinear.x) * (1.0 - bilinear.y),
                         bilinear.x * (1.0 - bilinear.y),
                         (1.0 - bilinear.x) * bilinear.y,
                         bilinear.x * bilinear.y);
  vec4 distance = abs(vec4(dot(vec4(p00, -1.0), scene_plane),
                           dot(vec4(p10, -1.0), scene_plane),
                           dot(vec4(p01, -1.0), scene_plane),
                           dot(vec4(p11, -1.0), scene_plane)));
  vec4 relative = distance / scene_depth;
  vec4 w_depth = exp2(-PROBE_PLANE_SHARPNESS * relative * relative);
  w_depth *= vec4(greaterThan(corner_valid, vec4(0.5)));
  vec4 w = w_bilinear * w_depth;
  w /= max(dot(w, vec4(1.0)), PROBE_WEIGHT_EPS);
  lighting_valid = dot(w, vec4(1.0)) < 1.0 - PROBE_WEIGHT_EPS ? 0.0 : 1.0;
  return w;
}

#endif /* LUMEN_PROBE_INTERP_LIB */
