// The common-path length of the operations src/cost.rs weighs, as nvcc compiles them
// with the twins' flags (cuda/build.sh): one kernel per operation, each loading its
// operands and storing its result, so that the SASS between the loads and the store is
// the operation. `sh cuda/probe_costs.sh` builds it and prints each kernel's SASS.
#define PROBE(name, expr)                                          \
    extern "C" __global__ void name(const float* a, float* o) {   \
        int i = threadIdx.x;                                       \
        o[i] = (expr);                                             \
    }

PROBE(probe_add, a[i] + a[i + 32])
PROBE(probe_div, a[i] / a[i + 32])
PROBE(probe_sqrt, sqrtf(a[i]))
PROBE(probe_exp, expf(a[i]))
PROBE(probe_sin, sinf(a[i]))
PROBE(probe_cos, cosf(a[i]))
PROBE(probe_tan, tanf(a[i]))
