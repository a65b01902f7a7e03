/* Surface cache indirect light: per lighting-atlas texel, `rays` cosine-distributed rays (a
 * Hammersley set rotated per texel and frame) through gi_trace; each returns the surface cache's
 * final light at its hit (last frame's: light bounces once more every frame) or the sky.
 * E_new = pi * mean(L); accumulated as E = mix(E_prev, E_new, blend).
 * Rays start one voxel of the texel's object off the surface, along its normal.
 * Inputs: texel_card, card tables and layers, sc_final (last frame), sc_indirect_prev; push
 * constants sky, rays, frame, blend, t_max. Output out_image: E.rgb, w = share of rays whose hit
 * no card saw (their light is lost: a coverage diagnostic).
 */
#define PI 3.14159265358979

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  int row = int(texelFetch(texel_card, px, 0).x);
  vec3 pl, nl, albedo, emissive;
  if (row < 0 || !sc_texel_surface(row, px - ivec2(sc_card(row, 0).zw + 0.5), pl, nl, albedo, emissive)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  int obj = int(sc_card(row, 0).x + 0.5);
  mat4 w2l = transpose(mat4(sdf_object_texel(obj, 0), sdf_object_texel(obj, 1),
                            sdf_object_texel(obj, 2), vec4(0.0, 0.0, 0.0, 1.0)));
  vec3 p = (inverse(w2l) * vec4(pl, 1.0)).xyz;
  vec3 n = normalize(transpose(mat3(w2l)) * nl);
  vec3 o = p + n * gi_object_voxel(obj);
  uint seed = pcg_hash(uint(px.x) + 4099u * uint(px.y)) ^ pcg_hash(uint(frame) + 0x68bc21ebu);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 sum = vec3(0.0);
  float lost = 0.0;
  for (int i = 0; i < rays; i++) {
    vec3 dir = cosine_hemisphere(fract(hammersley(uint(i), uint(rays)) + rot), n);
    float t, w;
    sum += gi_radiance(o, dir, t_max, sky, t, w);
    lost += w > 0.0 ? 0.0 : 1.0;
  }
  vec3 E = PI * sum / float(rays);
  vec3 prev = texelFetch(sc_indirect_prev, px, 0).rgb;
  imageStore(out_image, px, vec4(mix(prev, E, blend), lost / float(rays)));
}
