// 4.1: one draw per unit, the MVP and id as uniforms.
in vec3 in_pos;
uniform mat4 u_mvp;
uniform uint u_id;
flat out uint v_id;
void main() {
    gl_Position = u_mvp * vec4(in_pos, 1.0);
    v_id = u_id + 1u;
}
