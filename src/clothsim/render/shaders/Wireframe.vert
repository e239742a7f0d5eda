#version 330
// Springs as plain line segments.
uniform mat4 u_model;
uniform mat4 u_view_projection;

in vec4 in_position;

void main() {
    gl_Position = u_view_projection * u_model * in_position;
}
