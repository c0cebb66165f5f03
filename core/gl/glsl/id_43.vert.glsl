// 4.3: the MVP and object id are per-instance data of this draw, picked by baseInstance.
in vec3 in_pos;
in mat4 in_mvp;
in uint in_id;
flat out uint v_id;
void main() {
    gl_Position = in_mvp * vec4(in_pos, 1.0);
    v_id = in_id + 1u;
}
