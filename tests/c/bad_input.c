/* Bad input through the C API returns the documented status code and a message naming
 * the argument (docs/spec.md §10): NULL pointers, NaN parameters, unordered thresholds,
 * non-invertible weights, wrong lengths, unknown codes, unstable gains, reversed bounds,
 * uninitialized structs. Also: copies of initialized structs work, a failed init leaves a
 * struct that cannot be stepped, non-finite inputs leave the state untouched; tampered and
 * non-finite states and far references are refused with a status (issue 20).
 * Exit 0 when every check passes. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "piezohyst.h"

static int failures, checks;

#define EXPECT(call, code, needle) expect_status((call), (code), (needle), #call, __LINE__)

static void expect_status(PhsStatus got, PhsStatus want, const char *needle, const char *call, int line) {
    const char *msg = phs_last_error_message();
    checks++;
    if (got != want) {
        fprintf(stderr, "bad_input.c:%d: %s returned %s, expected %s (%s)\n", line, call, phs_status_name(got),
                phs_status_name(want), msg);
        failures++;
        return;
    }
    if (want != PHS_OK && phs_last_error() != want) {
        fprintf(stderr, "bad_input.c:%d: phs_last_error() = %s, expected %s\n", line, phs_status_name(phs_last_error()),
                phs_status_name(want));
        failures++;
    }
    if (needle && !strstr(msg, needle)) {
        fprintf(stderr, "bad_input.c:%d: %s: message \"%s\" does not mention \"%s\"\n", line, call, msg, needle);
        failures++;
    }
}

static void expect_true(int cond, const char *what, int line) {
    checks++;
    if (!cond) {
        fprintf(stderr, "bad_input.c:%d: %s\n", line, what);
        failures++;
    }
}
#define TRUE(cond) expect_true((cond), #cond, __LINE__)

static PhsModelSpec pi_spec(const double *row, size_t n_params) {
    PhsModelSpec s;
    memset(&s, 0, sizeof s);
    s.family = PHS_FAMILY_PI;
    s.n_dims = 2;
    s.dims[0] = 3; /* operators */
    s.dims[1] = 0; /* creep terms */
    s.params = row;
    s.n_params = n_params;
    return s;
}

int main(void) {
    /* p0, r[3], w[3] */
    const double good[7] = {0.9, 0.1, 0.4, 0.8, 0.5, -0.2, 0.3};
    const double nan_row[7] = {NAN, 0.1, 0.4, 0.8, 0.5, -0.2, 0.3};
    const double unordered[7] = {0.9, 0.1, 0.5, 0.3, 0.5, -0.2, 0.3};
    const double negative[7] = {0.9, -0.1, 0.4, 0.8, 0.5, -0.2, 0.3};
    const double not_invertible[7] = {1.0, 0.1, 0.4, 0.8, -0.4, -0.7, 0.3}; /* S_2 = 1 - 0.4 - 0.7 < 0 */
    PhsModelSpec spec = pi_spec(good, 7);
    PhsModel model, copy, broken, noninv;
    PhsController c;
    double state[3], y, v, u;
    size_t n;
    int k;

    /* status names and messages */
    TRUE(strcmp(phs_status_name(PHS_ERR_NOT_INVERTIBLE), "PHS_ERR_NOT_INVERTIBLE") == 0);
    TRUE(strcmp(phs_status_name(12345), "PHS_ERR_UNKNOWN_CODE") == 0);
    for (k = 0; k < PHS_STATUS_COUNT; k++) TRUE(strlen(phs_status_message(k)) > 0);
    TRUE(strlen(phs_version()) > 0);

    /* NULL pointers */
    EXPECT(phs_model_init(NULL, &spec, NULL, 0), PHS_ERR_NULL_POINTER, "model is NULL");
    EXPECT(phs_model_init(&model, NULL, NULL, 0), PHS_ERR_NULL_POINTER, "spec is NULL");
    spec.params = NULL;
    EXPECT(phs_model_init(&model, &spec, NULL, 0), PHS_ERR_NULL_POINTER, "spec->params is NULL");
    spec.params = good;
    EXPECT(phs_model_init(&model, &spec, NULL, 0), PHS_OK, NULL);
    EXPECT(phs_model_step(NULL, state, 3, 0.0, &y), PHS_ERR_NULL_POINTER, "model is NULL");
    EXPECT(phs_model_step(&model, NULL, 3, 0.0, &y), PHS_ERR_NULL_POINTER, "state is NULL");
    EXPECT(phs_model_step(&model, state, 3, 0.0, NULL), PHS_ERR_NULL_POINTER, "y_out is NULL");
    EXPECT(phs_controller_step(NULL, state, 3, 0, 0, 0, 0, &u), PHS_ERR_NULL_POINTER, "controller is NULL");

    /* NaN and infinite parameters, inputs */
    spec = pi_spec(nan_row, 7);
    EXPECT(phs_model_init(&broken, &spec, NULL, 0), PHS_ERR_NOT_FINITE, "p0 = NaN is not finite");
    TRUE(broken.magic == 0);
    EXPECT(phs_model_step(&broken, state, 3, 0.0, &y), PHS_ERR_NOT_INITIALIZED, "model was not initialized");
    EXPECT(phs_model_validate(&spec, NULL, 0), PHS_ERR_NOT_FINITE, "phs_model_validate: p0");
    EXPECT(phs_model_reset(&model, state, 3), PHS_OK, NULL);
    EXPECT(phs_model_step(&model, state, 3, 0.7, &y), PHS_OK, NULL);
    {
        double before[3];
        memcpy(before, state, sizeof state);
        EXPECT(phs_model_step(&model, state, 3, NAN, &y), PHS_ERR_NOT_FINITE, "v = NaN");
        EXPECT(phs_model_step(&model, state, 3, INFINITY, &y), PHS_ERR_NOT_FINITE, "v = inf");
        EXPECT(phs_model_inverse_step(&model, state, 3, NAN, 0.0, &v), PHS_ERR_NOT_FINITE, "y_desired = NaN");
        TRUE(memcmp(before, state, sizeof state) == 0);
    }

    /* thresholds: unordered, negative */
    spec = pi_spec(unordered, 7);
    EXPECT(phs_model_init(&broken, &spec, NULL, 0), PHS_ERR_NOT_INCREASING, "thresholds[2] = 0.3 is not greater than thresholds[1]");
    spec = pi_spec(negative, 7);
    EXPECT(phs_model_init(&broken, &spec, NULL, 0), PHS_ERR_INVALID_PARAMETER, "thresholds[0] = -0.1 must be >= 0");

    /* non-invertible weights: a valid forward model without an inverse */
    spec = pi_spec(not_invertible, 7);
    EXPECT(phs_model_init(&noninv, &spec, NULL, 0), PHS_OK, NULL);
    TRUE((noninv.flags & PHS_MODEL_FLAG_NOT_INVERTIBLE) != 0);
    EXPECT(phs_model_reset(&noninv, state, 3), PHS_OK, NULL);
    EXPECT(phs_model_step(&noninv, state, 3, 0.5, &y), PHS_OK, NULL);
    EXPECT(phs_model_inverse_step(&noninv, state, 3, 0.1, 0.0, &v), PHS_ERR_NOT_INVERTIBLE, "partial sum S[2]");
    {
        const double ff[6] = {1.0, 0.0, 0.0, 0.0, -1.0, 1.0};
        PhsInverse inv = {&noninv, -20.0, 150.0};
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_OPEN_LOOP, ff, 6, &inv, NULL), PHS_ERR_NOT_INVERTIBLE,
               "inverse->model: weights are not invertible");
    }

    /* lengths, codes */
    spec = pi_spec(good, 6);
    EXPECT(phs_model_init(&broken, &spec, NULL, 0), PHS_ERR_BAD_LENGTH, "spec->n_params = 6, expected 7");
    spec = pi_spec(good, 7);
    spec.n_dims = 1;
    EXPECT(phs_model_init(&broken, &spec, NULL, 0), PHS_ERR_BAD_LENGTH, "dims has length 1, expected 2");
    spec.n_dims = 9;
    EXPECT(phs_model_init(&broken, &spec, NULL, 0), PHS_ERR_BAD_LENGTH, "n_dims = 9");
    spec = pi_spec(good, 7);
    spec.family = 42;
    EXPECT(phs_model_init(&broken, &spec, NULL, 0), PHS_ERR_UNKNOWN_KIND, "family = 42 is unknown");
    spec = pi_spec(good, 7);
    EXPECT(phs_model_init(&broken, &spec, state, 3), PHS_ERR_BAD_LENGTH, "n_scratch = 3, expected 0");
    EXPECT(phs_model_step(&model, state, 2, 0.0, &y), PHS_ERR_BAD_LENGTH, "n_state = 2, expected 3");
    EXPECT(phs_controller_param_count(9, &n), PHS_ERR_UNKNOWN_KIND, "kind = 9 is unknown");
    EXPECT(phs_controller_param_count(PHS_CONTROLLER_ABSMC, &n), PHS_OK, NULL);
    TRUE(n == 22);

    /* a copy of an initialized model is a model; its outputs equal the original's */
    copy = model;
    {
        double s1[3], s2[3], y1, y2;
        phs_model_reset(&model, s1, 3);
        phs_model_reset(&copy, s2, 3);
        for (k = 0; k < 100; k++) {
            double x = sin(0.1 * k);
            EXPECT(phs_model_step(&model, s1, 3, x, &y1), PHS_OK, NULL);
            EXPECT(phs_model_step(&copy, s2, 3, x, &y2), PHS_OK, NULL);
            TRUE(y1 == y2);
        }
        /* the exact inverse: model(inverse(y)) == y */
        phs_model_reset(&model, s1, 3);
        phs_model_reset(&copy, s2, 3);
        v = 0.0;
        for (k = 0; k < 100; k++) {
            double yd = 0.5 * sin(0.07 * k), yb;
            EXPECT(phs_model_inverse_step(&model, s1, 3, yd, v, &v), PHS_OK, NULL);
            EXPECT(phs_model_step(&copy, s2, 3, v, &yb), PHS_OK, NULL);
            TRUE(fabs(yb - yd) <= 1e-12);
        }
    }

    /* controllers: NaN gains, unstable sliding dynamics, reversed limits and bounds */
    {
        /* PID: kp, ki, kd, tau_d, ts, ff_gain, offset, u_min, u_max */
        double pid[9] = {2e6, 2e9, 0.0, 1e-4, 1e-4, 7e6, 0.0, -20.0, 150.0};
        double smc[21] = {0.0068, 13.0, 6.98e6, 1e6, -2e3, 0.0, 0.0, 20.0, 0.01, 1000.0, 1e-4, 1.0,
                          0.0, 10.5, 1.8e-6, 1.25e5, 8000.0, 3000.0, 0.0, -20.0, 150.0};
        double absmc[22] = {1.0, 100.0, 1.0, 10.0, 0.1, 1000.0, 10.0, 2e3, 2e3, 5e3, 1e-3, 1e6, 1e3,
                            1e4, 0.0, 1e5, 1.0, 1000.0, 1e-4, 1.0, -20.0, 150.0};
        PhsIlcSpec ilc = {100, 0.3, 1.5, 3, 1};
        double st[300];
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_PID, pid, 8, NULL, NULL), PHS_ERR_BAD_LENGTH, "n_params = 8, expected 9");
        pid[1] = NAN;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_PID, pid, 9, NULL, NULL), PHS_ERR_NOT_FINITE, "params[1] = NaN");
        TRUE(c.magic == 0);
        pid[1] = 2e9;
        pid[7] = 200.0;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_PID, pid, 9, NULL, NULL), PHS_ERR_INVALID_PARAMETER, "u_max - u_min");
        pid[7] = -20.0;
        pid[0] = -1.0;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_PID, pid, 9, NULL, NULL), PHS_ERR_INVALID_PARAMETER, "kp = -1 must be >= 0");
        pid[0] = 2e6;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_SMC, smc, 21, NULL, NULL), PHS_ERR_INVALID_PARAMETER,
               "kv + alpha (sliding dynamics unstable)");
        smc[4] = 2e3;
        smc[6] = 2.0;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_SMC, smc, 21, NULL, NULL), PHS_ERR_INVALID_PARAMETER, "switching");
        smc[6] = 0.0;
        smc[9] = 6000.0; /* observer above Nyquist */
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_SMC, smc, 21, NULL, NULL), PHS_ERR_INVALID_PARAMETER, "observer_bandwidth");
        smc[9] = 1000.0;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_SMC, smc, 21, NULL, NULL), PHS_OK, NULL);
        absmc[3] = 200.0; /* theta_min > theta0 */
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_ABSMC, absmc, 22, NULL, NULL), PHS_ERR_INVALID_PARAMETER, "theta0");
        absmc[3] = 10.0;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_ABSMC, absmc, 22, NULL, &ilc), PHS_ERR_INVALID_PARAMETER, "ilc: forgetting");
        ilc.forgetting = 1.0;
        ilc.lead = 100;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_ABSMC, absmc, 22, NULL, &ilc), PHS_ERR_INVALID_PARAMETER, "lead and delay");
        ilc.lead = 3;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_ABSMC, absmc, 22, NULL, &ilc), PHS_OK, NULL);
        EXPECT(phs_controller_state_len(&c, &n), PHS_OK, NULL);
        TRUE(n == 5 + 1 + 2 * 100);
        EXPECT(phs_controller_reset(&c, st, n, 1e-6), PHS_OK, NULL);
        EXPECT(phs_controller_reset(&c, st, n, NAN), PHS_ERR_NOT_FINITE, "y0 = NaN");
        EXPECT(phs_controller_step(&c, st, n - 1, 0, 0, 0, 0, &u), PHS_ERR_BAD_LENGTH, "n_state = 205, expected 206");
        EXPECT(phs_controller_step(&c, st, n, 1e-6, 0, 0, NAN, &u), PHS_ERR_NOT_FINITE, "y = NaN");
        EXPECT(phs_controller_step(&c, st, n, INFINITY, 0, 0, 0, &u), PHS_ERR_NOT_FINITE, "x_ref = inf");
        for (k = 0; k < 1000; k++) {
            EXPECT(phs_controller_step(&c, st, n, 1e-6 * (1 + sin(0.01 * k)), 0, 0, 1e-6, &u), PHS_OK, NULL);
            TRUE(u >= -20.0 && u <= 150.0);
        }
        EXPECT(phs_controller_init(&c, 0, absmc, 22, NULL, NULL), PHS_ERR_UNKNOWN_KIND, "kind = 0 is unknown");
        EXPECT(phs_controller_step(&c, st, n, 0, 0, 0, 0, &u), PHS_ERR_NOT_INITIALIZED, "controller was not initialized");
    }

    /* hostile states (issue 20): a tampered Preisach memory length, NaN and infinite model
     * and controller states, a reference far beyond a controller's declared range behind
     * an inverse model; each a status naming the slot or value, the state untouched (and,
     * checked by the Makefile, nothing on stderr) */
    {
        /* lo, hi, offset, slope, w[4*5/2] */
        const double pre_row[14] = {-1.5, 1.5, 0.2, 0.3, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5};
        PhsModelSpec ps;
        PhsModel pre;
        double pre_scratch[10], pst[18], before[18];
        /* PID: kp, ki, kd, tau_d, ts, ff_gain, offset, u_min, u_max */
        const double pid[9] = {2e6, 2e9, 0.0, 1e-4, 1e-4, 7e6, 0.0, -20.0, 150.0};
        /* behind the inverse, the limits are metres: -0.5 .. 1.5 (the PI model's outputs) */
        const double lin[9] = {0.5, 100.0, 0.0, 1e-4, 1e-4, 1.0, 0.0, -0.5, 1.5};
        PhsInverse inv;
        double cst[8], cbefore[8];
        size_t len;
        memset(&ps, 0, sizeof ps);
        ps.family = PHS_FAMILY_PREISACH;
        ps.n_dims = 2;
        ps.dims[0] = 4;  /* levels */
        ps.dims[1] = 16; /* memory */
        ps.params = pre_row;
        ps.n_params = 14;
        EXPECT(phs_model_sizes(&ps, NULL, &n, &len), PHS_OK, NULL);
        TRUE(n == 18 && len == 10);
        EXPECT(phs_model_init(&pre, &ps, pre_scratch, 10), PHS_OK, NULL);
        EXPECT(phs_model_reset(&pre, pst, 18), PHS_OK, NULL);
        for (k = 0; k < 40; k++) EXPECT(phs_model_step(&pre, pst, 18, 1.2 * sin(0.3 * k), &y), PHS_OK, NULL);
        pst[1] = 1e9; /* the memory length slot */
        memcpy(before, pst, sizeof pst);
        EXPECT(phs_model_step(&pre, pst, 18, 0.3, &y), PHS_ERR_INVALID_PARAMETER, "state (memory length)[1] = 1000000000");
        EXPECT(phs_model_inverse_step(&pre, pst, 18, 0.3, 0.0, &v), PHS_ERR_INVALID_PARAMETER, "memory length");
        TRUE(memcmp(before, pst, sizeof pst) == 0);
        pst[1] = -3.0;
        EXPECT(phs_model_step(&pre, pst, 18, 0.3, &y), PHS_ERR_INVALID_PARAMETER, "must lie within [0, 16]");
        pst[1] = 2.5;
        EXPECT(phs_model_step(&pre, pst, 18, 0.3, &y), PHS_ERR_INVALID_PARAMETER, "state (memory length)[1] = 2.5");
        pst[1] = 0.0;
        EXPECT(phs_model_step(&pre, pst, 18, 0.3, &y), PHS_OK, NULL);

        /* the PI model's state: a NaN play was silently absorbed by max/min */
        EXPECT(phs_model_reset(&model, state, 3), PHS_OK, NULL);
        EXPECT(phs_model_step(&model, state, 3, 0.4, &y), PHS_OK, NULL);
        state[1] = NAN;
        EXPECT(phs_model_step(&model, state, 3, 0.4, &y), PHS_ERR_NOT_FINITE, "state[1] = NaN is not finite");
        EXPECT(phs_model_inverse_step(&model, state, 3, 0.1, 0.0, &v), PHS_ERR_NOT_FINITE, "state[1] = NaN");
        TRUE(isnan(state[1]));
        state[1] = -INFINITY;
        EXPECT(phs_model_step(&model, state, 3, 0.4, &y), PHS_ERR_NOT_FINITE, "state[1] = -inf");

        /* PID with a NaN or -inf state: drove the upper rail with PHS_OK */
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_PID, pid, 9, NULL, NULL), PHS_OK, NULL);
        EXPECT(phs_controller_reset(&c, cst, 3, 0.0), PHS_OK, NULL);
        EXPECT(phs_controller_step(&c, cst, 3, 1e-6, 0, 0, 0, &u), PHS_OK, NULL);
        cst[0] = NAN;
        memcpy(cbefore, cst, sizeof cst);
        u = 42.0;
        EXPECT(phs_controller_step(&c, cst, 3, 1e-6, 0, 0, 0, &u), PHS_ERR_NOT_FINITE, "state[0] = NaN is not finite");
        TRUE(u == 42.0);
        TRUE(memcmp(cbefore, cst, 3 * sizeof(double)) == 0);
        cst[0] = 0.0;
        cst[1] = -INFINITY;
        EXPECT(phs_controller_step(&c, cst, 3, 1e-6, 0, 0, 0, &u), PHS_ERR_NOT_FINITE, "state[1] = -inf");
        cst[1] = 0.0;
        cst[2] = INFINITY;
        EXPECT(phs_controller_step(&c, cst, 3, 1e-6, 0, 0, 0, &u), PHS_ERR_NOT_FINITE, "state[2] = inf");

        /* behind the PI inverse: a reference of 1e300 m is refused, a reachable one is not */
        inv.model = &model;
        inv.u_min = -20.0;
        inv.u_max = 150.0;
        EXPECT(phs_controller_init(&c, PHS_CONTROLLER_PID, lin, 9, &inv, NULL), PHS_OK, NULL);
        EXPECT(phs_controller_state_len(&c, &n), PHS_OK, NULL);
        TRUE(n == 3 + 3 + 1);
        EXPECT(phs_controller_reset(&c, cst, n, 0.0), PHS_OK, NULL);
        memcpy(cbefore, cst, n * sizeof(double));
        EXPECT(phs_controller_step(&c, cst, n, 1e300, 0, 0, 0, &u), PHS_ERR_UNREACHABLE, "x_ref = 1e300 m is outside [-2.5, 3.5]");
        EXPECT(phs_controller_step(&c, cst, n, -1e300, 0, 0, 0, &u), PHS_ERR_UNREACHABLE, "x_ref = -1e300");
        EXPECT(phs_controller_step(&c, cst, n, 3.6, 0, 0, 0, &u), PHS_ERR_UNREACHABLE, "x_ref = 3.6");
        TRUE(memcmp(cbefore, cst, n * sizeof(double)) == 0);
        EXPECT(phs_controller_step(&c, cst, n, 3.4, 0, 0, 0, &u), PHS_OK, NULL); /* beyond reach: saturates */
        TRUE(u >= -20.0 && u <= 150.0);
        EXPECT(phs_controller_step(&c, cst, n, 0.5, 0, 0, 0.4, &u), PHS_OK, NULL);
        cst[3] = NAN; /* the inverse model's state inside the controller's */
        EXPECT(phs_controller_step(&c, cst, n, 0.5, 0, 0, 0.4, &u), PHS_ERR_NOT_FINITE, "state[3] = NaN");
    }

    printf("bad_input: %d checks, %d failed\n", checks, failures);
    return failures == 0 ? 0 : 1;
}
