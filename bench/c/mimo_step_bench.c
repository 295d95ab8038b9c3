/* ns per step of a MIMO model (issue 15: an LFR, a discrete state space with play operators in
 * a feedback path) from C, through libpiezohyst's phs_mimo_step: what a real-time loop of a
 * 3-actuator / 3-sensor mirror pays per sample. Single thread; each case is fed a
 * pseudo-random input of 0.3 V per channel (xorshift64*, fixed seed).
 *
 * The last case has the dims of the LFR identify_mimo fits to the CubeSpec mirror's records
 * (examples/data/fsm_lfr_123.json: 120 states, 12 feedback channels of 1 play).
 *
 * Per case (dims nx nu ny nw nr): mean ns per step over STEPS steps (best of RUNS runs, one
 * clock read around the loop) and every step timed on its own (median, 99.9th percentile,
 * worst; these include one clock read). Prints JSON on stdout.
 *
 * Build: cc -std=c99 -O2 -I crates/capi/include bench/c/mimo_step_bench.c \
 *            target/release/libpiezohyst.a -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc
 * (bench/mimo_c_step.py builds, runs and writes bench/results/mimo_c_step.json). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "piezohyst.h"

#define STEPS 200000
#define RUNS 5
#define NU 3

static float lap[STEPS];
static double uin[STEPS * NU];

static double now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double rnd(void) { /* [-1, 1) */
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (double)((rng_state * 0x2545F4914F6CDD1Dull) >> 11) / 4503599627370496.0 - 1.0;
}

static void ok(PhsStatus s, const char *what) {
    if (s != PHS_OK) {
        fprintf(stderr, "mimo_step_bench: %s: %s (%s)\n", what, phs_status_name(s), phs_last_error_message());
        exit(1);
    }
}

static int by_value(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* A stable model of these dims: rotation blocks of radius 0.9-0.97 in A, small random couplings. */
static double *make_row(size_t nx, size_t nw, size_t nr, size_t *len) {
    size_t ny = 3, nu = NU, k = 0, i;
    size_t n = nx * nx + nx * nu + ny * nx + ny * nu + nx * nw + ny * nw + nw * nx + nw * nu + 2 * nw * nr;
    double *row = calloc(n, sizeof *row);
    for (i = 0; i + 1 < nx; i += 2) {
        double r = 0.9 + 0.07 * (double)i / (double)nx, th = 0.2 + 0.3 * (double)i;
        row[i * nx + i] = r * cos(th);
        row[i * nx + i + 1] = -r * sin(th);
        row[(i + 1) * nx + i] = r * sin(th);
        row[(i + 1) * nx + i + 1] = r * cos(th);
    }
    if (nx % 2) row[nx * nx - 1] = 0.5;
    k = nx * nx;
    for (i = 0; i < nx * nu; i++) row[k++] = rnd();            /* B */
    for (i = 0; i < ny * nx; i++) row[k++] = 1e-6 * rnd();     /* C */
    for (i = 0; i < ny * nu; i++) row[k++] = 1e-7 * rnd();     /* D */
    for (i = 0; i < nx * nw; i++) row[k++] = 0.05 * rnd();     /* E */
    for (i = 0; i < ny * nw; i++) row[k++] = 1e-8 * rnd();     /* F */
    for (i = 0; i < nw * nx; i++) row[k++] = 0.1 * rnd();      /* G */
    for (i = 0; i < nw * nu; i++) row[k++] = rnd();            /* H */
    for (i = 0; i < nw * nr; i++) row[k++] = 0.3 * (double)(i % nr) / (double)nr; /* thresholds */
    for (i = 0; i < nw * nr; i++) row[k++] = 0.3 * rnd();      /* weights */
    *len = n;
    return row;
}

static void bench(const char *name, size_t nx, size_t nw, size_t nr, int first) {
    size_t len, n_state, n_work, i, t;
    double *row = make_row(nx, nw, nr, &len);
    PhsMimoSpec spec = {nx, NU, 3, nw, nr, 0, row, len};
    PhsMimo m;
    double best = 1e300, y[3], sink = 0.0;
    double *state, *work;
    ok(phs_mimo_init(&m, &spec), "init");
    ok(phs_mimo_state_len(&m, &n_state, &n_work), "state_len");
    state = calloc(n_state, sizeof *state);
    work = calloc(n_work, sizeof *work);
    for (i = 0; i < RUNS; i++) {
        double t0, t1;
        ok(phs_mimo_reset(&m, state, n_state), "reset");
        t0 = now_ns();
        for (t = 0; t < STEPS; t++) {
            phs_mimo_step(&m, state, n_state, work, n_work, &uin[t * NU], NU, y, 3);
            sink += y[0];
        }
        t1 = now_ns();
        if ((t1 - t0) / STEPS < best) best = (t1 - t0) / STEPS;
    }
    ok(phs_mimo_reset(&m, state, n_state), "reset");
    for (t = 0; t < STEPS; t++) {
        double t0 = now_ns();
        ok(phs_mimo_step(&m, state, n_state, work, n_work, &uin[t * NU], NU, y, 3), "step");
        lap[t] = (float)(now_ns() - t0);
        sink += y[1];
    }
    qsort(lap, STEPS, sizeof lap[0], by_value);
    printf("%s    \"%s\": {\"nx\": %zu, \"nw\": %zu, \"nr\": %zu, \"params\": %zu, \"state\": %zu, "
           "\"mean\": %.2f, \"median\": %.1f, \"p99.9\": %.1f, \"worst\": %.1f, \"sink\": %.3g}",
           first ? "" : ",\n", name, nx, nw, nr, len, n_state, best, (double)lap[STEPS / 2],
           (double)lap[(size_t)(0.999 * STEPS)], (double)lap[STEPS - 1], sink);
    free(state);
    free(work);
    free(row);
}

int main(void) {
    size_t t;
    double c0, c1;
    for (t = 0; t < STEPS * NU; t++) uin[t] = 0.3 * rnd();
    c0 = now_ns();
    for (t = 0; t < STEPS; t++) lap[t] = (float)now_ns();
    c1 = now_ns();
    printf("{\n  \"steps\": %d,\n  \"clock_read_ns\": %.2f,\n  \"results\": {\n", STEPS, (c1 - c0) / STEPS);
    bench("linear nx=28 (3x3)", 28, 0, 0, 1);
    bench("hammerstein-size nx=12 nw=3 nr=8", 12, 3, 8, 0);
    bench("lfr nx=28 nw=3 nr=10", 28, 3, 10, 0);
    bench("lfr nx=28 nw=3 nr=20", 28, 3, 20, 0);
    bench("fsm-size lfr nx=120 nw=12 nr=1", 120, 12, 1, 0);
    printf("\n  }\n}\n");
    return 0;
}
