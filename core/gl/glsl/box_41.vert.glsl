// 4.1: triangle-list vertices of every box in one buffer, one query object per box.
in vec3 in_pos;
uniform mat4 u_vp;
void main() { gl_Position = u_vp * vec4(in_pos, 1.0); }
