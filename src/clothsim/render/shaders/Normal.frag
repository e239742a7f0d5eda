#version 330
// The surface normal mapped from [-1, 1] to a colour in [0, 1].
in vec4 v_normal;
out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal.xyz);
    if (!gl_FrontFacing) n = -n;
    out_color = vec4(0.5 * n + 0.5, 1.0);
}
