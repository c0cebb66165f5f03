// The flag variant (what the engine uses unless a visible threshold needs counts; the
// README's GL figures).
layout(early_fragment_tests) in;
flat in int v_box;
layout(std430, binding = 0) buffer Samples { uint samples[]; };
void main() { samples[v_box] = 1u; }
