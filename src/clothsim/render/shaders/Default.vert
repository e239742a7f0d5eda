#version 330
// Passes world-space position, normal, tangent and uv to the fragment stage.
uniform mat4 u_model;
uniform mat4 u_view_projection;

in vec4 in_position;
in vec4 in_normal;
in vec4 in_tangent;
in vec2 in_uv;

out vec4 v_position;
out vec4 v_normal;
out vec4 v_tangent;
out vec2 v_uv;

void main() {
    v_position = u_model * in_position;
    v_normal = normalize(u_model * vec4(in_normal.xyz, 0.0));
    v_tangent = u_model * vec4(in_tangent.xyz, 0.0);
    v_uv = in_uv;
    gl_Position = u_view_projection * v_position;
}
