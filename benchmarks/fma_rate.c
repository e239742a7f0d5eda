/* fma_rate.c -- how many double-precision multiply-adds this core finishes a
 * nanosecond, at 256 and 512 bits, and how long one takes in a dependent chain.
 *
 * Twelve independent chains of vector multiply-adds give the throughput; one
 * chain, each step waiting on the last, gives the latency. With the latency's
 * cycles known for the core (four on Intel's cores since Skylake and on Zen
 * 4), the two give the clock and the multiply-adds a cycle: the roof the
 * springs' vector code is held against (docs/performance.md, "The eights with
 * AVX-512 on this core, against its bound").
 *
 * build: cc -O2 -march=native -o fma_rate fma_rate.c   (on a CPU without AVX-512 it
 *        times the 256-bit chains alone, and prints -1 for the 512-bit ones)
 * usage: fma_rate [steps]   (default 20000000 a chain and round, five rounds, the best kept)
 * prints one JSON object: {"ns_per_fma_512": t, "ns_per_fma_256": t, "ns_per_dependent_fma": t, ...};
 * a steps count that is not a positive number gets one line on stderr and exit status 2
 */
#include <immintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define ROUNDS 5

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

#define TWELVE(OP, c, a, b)                                                                  \
    c[0] = OP(c[0], a, b); c[1] = OP(c[1], a, b); c[2] = OP(c[2], a, b); c[3] = OP(c[3], a, b); \
    c[4] = OP(c[4], a, b); c[5] = OP(c[5], a, b); c[6] = OP(c[6], a, b); c[7] = OP(c[7], a, b); \
    c[8] = OP(c[8], a, b); c[9] = OP(c[9], a, b); c[10] = OP(c[10], a, b); c[11] = OP(c[11], a, b)

/* the best time of ROUNDS rounds of STEPS runs of BODY, in seconds, into OUT */
#define BEST_OF(OUT, BODY)                                  \
    do {                                                    \
        OUT = 1e9;                                          \
        for (int r = 0; r < ROUNDS; r++) {                  \
            double t0 = now();                              \
            for (long i = 0; i < STEPS; i++) { BODY; }      \
            double t1 = now() - t0;                         \
            OUT = t1 < OUT ? t1 : OUT;                      \
        }                                                   \
    } while (0)

int main(int argc, char **argv)
{
    long STEPS = 20000000L;
    if (argc > 1) {
        char *end;
        STEPS = strtol(argv[1], &end, 10);
        if (*argv[1] == '\0' || *end != '\0' || STEPS <= 0) {
            fprintf(stderr, "fma_rate: steps must be a positive whole number, not '%s'\n", argv[1]);
            return 2;
        }
    }
    volatile double seed = 0.1; /* distinct starts the compiler cannot fold together */
    double sink = 0.0, best;
    __m256d a4 = _mm256_set1_pd(1.0000001), b4 = _mm256_set1_pd(0.9999999), c4[12], one4;
    for (int k = 0; k < 12; k++) c4[k] = _mm256_set1_pd(seed + k);
    one4 = c4[0];
    BEST_OF(best, one4 = _mm256_fmadd_pd(one4, a4, b4));
    double dependent = best / STEPS * 1e9;
    BEST_OF(best, TWELVE(_mm256_fmadd_pd, c4, a4, b4));
    double per256 = best / (12.0 * STEPS) * 1e9;
    for (int k = 0; k < 12; k++) sink += _mm256_cvtsd_f64(c4[k]);
    sink += _mm256_cvtsd_f64(one4);
    double per512 = -1.0;
#ifdef __AVX512F__
    __m512d a8 = _mm512_set1_pd(1.0000001), b8 = _mm512_set1_pd(0.9999999), c8[12];
    for (int k = 0; k < 12; k++) c8[k] = _mm512_set1_pd(seed + k);
    BEST_OF(best, TWELVE(_mm512_fmadd_pd, c8, a8, b8));
    per512 = best / (12.0 * STEPS) * 1e9;
    for (int k = 0; k < 12; k++) sink += _mm512_reduce_add_pd(c8[k]);
#endif
    printf("{\"ns_per_fma_512\": %.4f, \"ns_per_fma_256\": %.4f, \"ns_per_dependent_fma\": %.4f, \"sink\": %g}\n",
           per512, per256, dependent, sink);
    return 0;
}
