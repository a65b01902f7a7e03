#include "row_table_lib.glsl"
/* Lumen GI G-buffer, instanced vertex stage (mesh_batches.py): a unique mesh's local-space
 * corners drawn once per instance with draw_instanced; the instance's row of the instance table
 * (`instances`, RGBA32F, 6 texels per row: the model matrix's rows 0..2, then the normal
 * matrix's rows 0..2, the inverse transpose of its 3x3; texel 3's w is 1 for a holdout) is
 * instance_base + gl_InstanceID.
 * Vertex inputs: pos, nor, tan (local), uv, albedo, emit (per corner, as gbuffer.glsl's).
 * Push constants: view_proj, instance_base (and the fragment stage's: use_albedo_tex,
 * use_emit_tex, albedo_base_h, emit_base_h, footprint_scale). The fragment stage is gbuffer.glsl's.
 */
void main()
{
  int row = instance_base + gl_InstanceID;
  vec4 m0 = texelFetch(instances, row_texel(row, 0, 6), 0);
  vec4 m1 = texelFetch(instances, row_texel(row, 1, 6), 0);
  vec4 m2 = texelFetch(instances, row_texel(row, 2, 6), 0);
  vec3 n0 = texelFetch(instances, row_texel(row, 3, 6), 0).xyz;
  vec3 n1 = texelFetch(instances, row_texel(row, 4, 6), 0).xyz;
  vec3 n2 = texelFetch(instances, row_texel(row, 5, 6), 0).xyz;
  vec4 p = vec4(pos, 1.0);
  vec3 world = vec3(dot(m0, p), dot(m1, p), dot(m2, p));
  vec3 n = vec3(dot(n0, nor), dot(n1, nor), dot(n2, nor));
  float len = length(n);
  v_pos = world;
  v_nor = len > 0.0 ? n / len : n;
  v_uv = uv;
  v_tan = vec4(dot(m0.xyz, tan.xyz), dot(m1.xyz, tan.xyz), dot(m2.xyz, tan.xyz), tan.w);
  v_albedo = albedo;
  v_emit = emit;
  v_holdout = texelFetch(instances, row_texel(row, 3, 6), 0).w;   /* 1: a holdout */
  gl_Position = view_proj * vec4(world, 1.0);
}
