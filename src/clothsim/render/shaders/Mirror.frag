#version 330
// A perfect mirror: the camera ray reflected about the normal, looked up in
// the environment cube map.
uniform vec3 u_cam_pos;
uniform samplerCube u_texture_cubemap;

in vec4 v_position;
in vec4 v_normal;
out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal.xyz);
    if (!gl_FrontFacing) n = -n;
    vec3 incoming = normalize(v_position.xyz - u_cam_pos);
    vec3 r = reflect(incoming, n);
    out_color = vec4(texture(u_texture_cubemap, r).rgb, 1.0);
}
