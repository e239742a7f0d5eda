#version 330
// Displacement mapping: vertices move along the normal by the height map, so
// the silhouette changes; shading is the same as Bump.
uniform mat4 u_model;
uniform mat4 u_view_projection;
uniform sampler2D u_texture_2;
uniform float u_height_scaling;

in vec4 in_position;
in vec4 in_normal;
in vec4 in_tangent;
in vec2 in_uv;

out vec4 v_position;
out vec4 v_normal;
out vec4 v_tangent;
out vec2 v_uv;

void main() {
    vec3 n = normalize(in_normal.xyz);
    float h = texture(u_texture_2, in_uv).r;
    vec4 displaced = vec4(in_position.xyz + n * h * u_height_scaling, 1.0);
    v_position = u_model * displaced;
    v_normal = normalize(u_model * vec4(n, 0.0));
    v_tangent = u_model * vec4(in_tangent.xyz, 0.0);
    v_uv = in_uv;
    gl_Position = u_view_projection * v_position;
}
