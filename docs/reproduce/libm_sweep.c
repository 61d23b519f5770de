// For docs/reproduce/libm-variants.sh: a hash of every float input's result for the
// float functions, and of 2^26 random inputs' for the double ones and for powf, so
// that runs under two of glibc's ifunc variants can be compared. One line per function.
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdint.h>
#include <string.h>
static uint64_t mix(uint64_t h, uint64_t v) { return (h ^ v) * 1099511628211ULL; }
static uint64_t rng = 88172645463325252ULL;
static uint64_t next(void) { rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17; return rng; }
typedef float (*f1)(float);
typedef double (*d1)(double);
static float sinf_(float x) { float s, c; sincosf(x, &s, &c); return s; }
static float cosf_(float x) { float s, c; sincosf(x, &s, &c); return c; }
static double sin_(double x) { double s, c; sincos(x, &s, &c); return s; }
static double cos_(double x) { double s, c; sincos(x, &s, &c); return c; }
int main(void) {
    struct { const char* n; f1 f; } fs[] = {{"expf", expf}, {"exp2f", exp2f}, {"logf", logf}, {"log2f", log2f},
        {"cosf", cosf}, {"sincosf.sin", sinf_}, {"sincosf.cos", cosf_}, {"tanf", tanf}, {"expm1f", expm1f}, {"log1pf", log1pf}};
    for (unsigned k = 0; k < sizeof fs / sizeof fs[0]; k++) {
        uint64_t h = 1469598103934665603ULL;
        for (uint64_t i = 0; i < (1ULL << 32); i++) {
            uint32_t b = (uint32_t)i; float x; memcpy(&x, &b, 4);
            float y = fs[k].f(x); uint32_t a; memcpy(&a, &y, 4); h = mix(h, a);
        }
        printf("%s every float %016lx\n", fs[k].n, h); fflush(stdout);
    }
    struct { const char* n; d1 f; } ds[] = {{"exp", exp}, {"log", log}, {"atan", atan}, {"cos", cos}, {"tan", tan}, {"sincos.sin", sin_}, {"sincos.cos", cos_}, {"log10", log10}};
    for (unsigned k = 0; k < sizeof ds / sizeof ds[0]; k++) {
        uint64_t h = 1469598103934665603ULL; rng = 88172645463325252ULL;
        for (uint64_t i = 0; i < (1ULL << 26); i++) {
            // Half the inputs uniform in [-40, 40], half random finite bit patterns.
            uint64_t r = next(); double x;
            if (i & 1) { x = ((double)(r >> 11) / 9007199254740992.0) * 80.0 - 40.0; }
            else { memcpy(&x, &r, 8); if (!isfinite(x)) x = 0.5; }
            double y = ds[k].f(x); uint64_t a; memcpy(&a, &y, 8); h = mix(h, a);
        }
        printf("%s 2^26 random %016lx\n", ds[k].n, h); fflush(stdout);
    }
    {
        uint64_t h = 1469598103934665603ULL; rng = 88172645463325252ULL;
        for (uint64_t i = 0; i < (1ULL << 26); i++) {
            uint64_t r = next(); float x = (float)((r >> 40) / 16777216.0) * 4.0f, e = (float)(((r >> 8) & 0xffffff) / 16777216.0) * 200.0f - 100.0f;
            float y = powf(x, e); uint32_t a; memcpy(&a, &y, 4); h = mix(h, a);
            double yd = pow((double)x, (double)e); uint64_t ad; memcpy(&ad, &yd, 8); h = mix(h, ad);
        }
        printf("powf,pow 2^26 random %016lx\n", h);
    }
}
