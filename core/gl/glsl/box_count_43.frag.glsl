// Only fragments that passed the depth test run (early tests), each adds one sample to
// its box: the same count a GL_SAMPLES_PASSED query gives for a single-sampled target.
layout(early_fragment_tests) in;
flat in int v_box;
layout(std430, binding = 0) buffer Samples { uint samples[]; };
void main() { atomicAdd(samples[v_box], 1u); }
