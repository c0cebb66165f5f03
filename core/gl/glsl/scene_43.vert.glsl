// 4.3: the MVP is per-instance data of this draw, picked by baseInstance.
in vec3 in_pos;
in mat4 in_mvp;
void main() { gl_Position = in_mvp * vec4(in_pos, 1.0); }
