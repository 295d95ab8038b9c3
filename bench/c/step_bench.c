/* ns per step of the compensators and controllers from C, through libpiezohyst (the C ABI
 * of crates/capi): what a 10-50 kHz real-time loop pays per sample. Single thread, no
 * plant: each object is fed an 80 Hz scan and its quantized reading (as
 * crates/core/examples/controller_step.rs does for the Rust API).
 *
 * Per case: mean ns per step over STEPS steps (best of RUNS runs, one clock read around
 * the whole loop), then every step timed on its own over STEPS steps for the distribution
 * (median, 99.9th percentile, worst); per-step times include one clock read (the overhead
 * is measured and reported, not subtracted). Prints JSON on stdout.
 *
 * Build: cc -std=c99 -O2 -I crates/capi/include bench/c/step_bench.c \
 *            target/release/libpiezohyst.a -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc
 * (bench/c_step.py builds, runs and writes bench/results/c_step.json). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "piezohyst.h"

#define STEPS 1000000
#define RUNS 5
#define TS 1e-4

static double xr[STEPS], vr[STEPS], ar[STEPS], ym[STEPS];
static float lap[STEPS];

static double now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

static void ok(PhsStatus s, const char *what) {
    if (s != PHS_OK) {
        fprintf(stderr, "step_bench: %s: %s (%s)\n", what, phs_status_name(s), phs_last_error_message());
        exit(1);
    }
}

static int by_value(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

typedef struct {
    double mean, median, p999, worst;
} Timing;

static Timing summarize(double best) {
    Timing t;
    qsort(lap, STEPS, sizeof lap[0], by_value);
    t.mean = best;
    t.median = lap[STEPS / 2];
    t.p999 = lap[(size_t)(0.999 * STEPS)];
    t.worst = lap[STEPS - 1];
    return t;
}

/* a controller: best mean over RUNS, then per-step laps */
static Timing time_controller(const PhsController *c) {
    static double state[4096];
    size_t n;
    double best = INFINITY, sink = 0.0, u;
    int run;
    long k;
    ok(phs_controller_state_len(c, &n), "state_len");
    if (n > 4096) exit(1);
    for (run = 0; run < RUNS; run++) {
        double t0;
        ok(phs_controller_reset(c, state, n, ym[0]), "reset");
        t0 = now_ns();
        for (k = 0; k < STEPS; k++) {
            phs_controller_step(c, state, n, xr[k], vr[k], ar[k], ym[k], &u);
            sink += u;
        }
        t0 = (now_ns() - t0) / STEPS;
        if (t0 < best) best = t0;
    }
    ok(phs_controller_reset(c, state, n, ym[0]), "reset");
    for (k = 0; k < STEPS; k++) {
        double t0 = now_ns();
        ok(phs_controller_step(c, state, n, xr[k], vr[k], ar[k], ym[k], &u), "step");
        lap[k] = (float)(now_ns() - t0);
        sink += u;
    }
    if (!isfinite(sink)) exit(1);
    return summarize(best);
}

/* a model's exact inverse as a compensator: desired output in, voltage out */
static Timing time_inverse(const PhsModel *m) {
    static double state[4096];
    size_t n = m->state_len;
    double best = INFINITY, sink = 0.0, v = 0.0;
    int run;
    long k;
    for (run = 0; run < RUNS; run++) {
        double t0;
        ok(phs_model_reset(m, state, n), "reset");
        v = 0.0;
        t0 = now_ns();
        for (k = 0; k < STEPS; k++) {
            phs_model_inverse_step(m, state, n, xr[k], v, &v);
            sink += v;
        }
        t0 = (now_ns() - t0) / STEPS;
        if (t0 < best) best = t0;
    }
    ok(phs_model_reset(m, state, n), "reset");
    v = 0.0;
    for (k = 0; k < STEPS; k++) {
        double t0 = now_ns();
        ok(phs_model_inverse_step(m, state, n, xr[k], v, &v), "inverse_step");
        lap[k] = (float)(now_ns() - t0);
        sink += v;
    }
    if (!isfinite(sink)) exit(1);
    return summarize(best);
}

static void print(const char *name, Timing t, int last) {
    printf("    \"%s\": {\"mean\": %.1f, \"median\": %.0f, \"p99.9\": %.0f, \"worst\": %.0f}%s\n", name, t.mean, t.median,
           t.p999, t.worst, last ? "" : ",");
}

int main(void) {
    /* seed 2's MPI structure: 9 generalized plays, cubic polynomial, identity envelopes (V -> m) */
    double mpi[14 + 18] = {0}, pi[1 + 18];
    double w = 2.0 * 3.141592653589793 * 80.0, w2 = pow(2.0 * 3.141592653589793 * 2000.0, 2.0);
    PhsModelSpec mpi_spec, pi_spec;
    PhsModel mpi_model, pi_model;
    PhsController c;
    PhsInverse inv;
    double clock_overhead;
    long k;
    int i;
    memset(&mpi_spec, 0, sizeof mpi_spec);
    memset(&pi_spec, 0, sizeof pi_spec);
    mpi[0] = -100.0;
    mpi[1] = 250.0;
    mpi[3] = 0.13e-6;
    pi[0] = 0.13e-6;
    for (i = 0; i < 9; i++) {
        mpi[14 + i] = 15.0 * i;
        mpi[14 + 9 + i] = 0.01e-6 / (1.0 + i);
        pi[1 + i] = 15.0 * i;
        pi[1 + 9 + i] = 0.01e-6 / (1.0 + i);
    }
    mpi_spec.family = PHS_FAMILY_GPI;
    mpi_spec.n_dims = 4;
    mpi_spec.dims[0] = 9;
    mpi_spec.params = mpi;
    mpi_spec.n_params = 32;
    pi_spec.family = PHS_FAMILY_PI;
    pi_spec.n_dims = 2;
    pi_spec.dims[0] = 9;
    pi_spec.params = pi;
    pi_spec.n_params = 19;
    ok(phs_model_init(&mpi_model, &mpi_spec, NULL, 0), "mpi init");
    ok(phs_model_init(&pi_model, &pi_spec, NULL, 0), "pi init");
    inv.model = &mpi_model;
    inv.u_min = -20.0;
    inv.u_max = 150.0;

    /* an 80 Hz scan read through a 0.1 um quantizer with a small tracking error */
    for (k = 0; k < STEPS; k++) {
        double t = (double)k * TS;
        xr[k] = 9e-6 + 8e-6 * sin(w * t);
        vr[k] = 8e-6 * w * cos(w * t);
        ar[k] = -8e-6 * w * w * sin(w * t);
        ym[k] = round((xr[k] + 2e-8 * sin((double)k * 0.37)) / 1e-7) * 1e-7;
    }
    {
        double t0 = now_ns();
        for (k = 0; k < STEPS; k++) lap[k] = (float)(now_ns() - now_ns());
        clock_overhead = (now_ns() - t0) / STEPS / 2.0;
    }

    printf("{\"steps\": %d, \"runs\": %d, \"unit\": \"ns\", \"clock_read_ns\": %.1f,\n  \"results\": {\n", STEPS, RUNS,
           clock_overhead);
    print("PI inverse, 9 operators (phs_model_inverse_step)", time_inverse(&pi_model), 0);
    print("MPI inverse, 9 operators (phs_model_inverse_step)", time_inverse(&mpi_model), 0);
    {
        /* inverse feedforward: open loop (unit gain, m) behind the MPI inverse */
        const double p[6] = {1.0, 0.0, 0.0, 0.0, -2e-6, 22e-6};
        ok(phs_controller_init(&c, PHS_CONTROLLER_OPEN_LOOP, p, 6, &inv, NULL), "open loop");
        print("MPI inverse feedforward (open loop behind the inverse)", time_controller(&c), 0);
    }
    {
        double p[21] = {0.0068, 13.0, 6.98e6, 1e6, 2e3, 0.0, 0.0, 20.0, 0.01, 1000.0, TS, 1.0,
                        0.0, 10.5, 1.8e-6, 1.25e5, 8000.0, 3000.0, 0.0, -20.0, 150.0};
        ok(phs_controller_init(&c, PHS_CONTROLLER_SMC, p, 21, NULL, NULL), "smc");
        print("SMC", time_controller(&c), 0);
        p[12] = 1.0;
        ok(phs_controller_init(&c, PHS_CONTROLLER_SMC, p, 21, NULL, NULL), "smc+cemf");
        print("SMC + CEMF observer", time_controller(&c), 0);
    }
    {
        /* SMC in the linearized (displacement) domain behind the MPI inverse */
        const double p[21] = {1.0 / w2, 1.4 / sqrt(w2), 1.0, 1e6, 2e3, 0.0, 0.0, 1e-6, 0.01, 1000.0, TS, 1.0,
                              0.0, 10.5, 1.8e-6, 1.25e5, 8000.0, 3000.0, 0.0, -2e-6, 22e-6};
        ok(phs_controller_init(&c, PHS_CONTROLLER_SMC, p, 21, &inv, NULL), "mpi+smc");
        print("MPI inverse (9 operators) + SMC", time_controller(&c), 0);
    }
    {
        const double p[22] = {w2, w2, 1.4 * sqrt(w2), w2 / 3.0, 0.0, 3.0 * w2, 3.0 * sqrt(w2), 2e3, 2e3, 5e3, 1e-3,
                              1e6, 1e3, 1e4, 0.0, 1e5, 1.0, 1000.0, TS, 1.0, -2e-6, 22e-6};
        ok(phs_controller_init(&c, PHS_CONTROLLER_ABSMC, p, 22, &inv, NULL), "mpi+absmc");
        print("MPI inverse (9 operators) + ABSMC", time_controller(&c), 1);
    }
    printf("  }\n}\n");
    return 0;
}
