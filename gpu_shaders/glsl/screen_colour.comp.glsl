/* The radiance a screen-trace hit reads (screen_trace.py; the lecture reads last frame's scene
 * colour): per G-buffer pixel albedo x (E_direct + E_indirect) / pi + emission, with the direct
 * light of this frame's direct pass at full resolution and E_indirect from the surface cache
 * (bound as sc_final: the `indirect` irradiance atlas), sampled at the pixel as
 * surface_cache_view.comp.glsl does. So a hit sees the same bounces as an SDF hit on the cache,
 * the same every F12 iteration and on the first viewport frame after a move (no history to
 * reproject). Where no card sees the pixel it has no indirect term.
 * Inputs: gbuf_position, gbuf_normal, gbuf_albedo, gbuf_emission, direct (E_direct / pi);
 * cam_pos. Output out_image: rgb radiance, w 1 (0 on the background).
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  float h;
  int obj;
  sdf_scene(p, h, obj);
  vec3 e_ind = vec3(0.0);
  if (obj >= 0) {
    mat4 w2l = sc_object_w2l(obj);
    vec3 pl = (w2l * vec4(p, 1.0)).xyz;
    vec3 nl = normalize(transpose(inverse(mat3(w2l))) * n);
    float weight;
    vec3 v = sc_sample_local(obj, pl, nl, sdf_object_texel(obj, 4).w, inverse(w2l),
                             gi_object_voxel(obj), weight);
    e_ind = weight > 0.0 ? v : vec3(0.0);
  }
  vec3 albedo = texelFetch(gbuf_albedo, px, 0).rgb;
  vec3 emission = texelFetch(gbuf_emission, px, 0).rgb;
  vec3 direct = texelFetch(direct, px, 0).rgb;
  imageStore(out_image, px, vec4(albedo * (direct + e_ind / 3.14159265358979) + emission, 1.0));
}
