// The scene's vertices, for the depth pass and (WITH_ID) the object-ID pass.
// 4.3: the MVP and object id are per-instance data of the draw, picked by baseInstance;
// 4.1: one draw per unit, both as uniforms.
in vec3 in_pos;
#if __VERSION__ >= 430
in mat4 in_mvp;
#define MVP in_mvp
#ifdef WITH_ID
in uint in_id;
#define OBJECT_ID in_id
#endif
#else
uniform mat4 u_mvp;
#define MVP u_mvp
#ifdef WITH_ID
uniform uint u_id;
#define OBJECT_ID u_id
#endif
#endif
#ifdef WITH_ID
flat out uint v_id;
#endif
void main() {
    gl_Position = MVP * vec4(in_pos, 1.0);
#ifdef WITH_ID
    v_id = OBJECT_ID + 1u;
#endif
}
