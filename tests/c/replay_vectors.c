/* Replay the shared test vectors of tests/c/gen_vectors.py through libpiezohyst: every model
 * family forward and inverse, every controller kind (alone, behind an identified MPI
 * inverse, with ILC) must give Python's outputs to 1e-12 (relative); bit-identical is
 * expected, and the count of bit-identical values is reported.
 *
 * Usage: replay_vectors VECTORS.txt   (exit 0 when everything matches) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "piezohyst.h"

#define TOLERANCE 1e-12

static char *cursor;
static const char *path;

static void die(const char *what) {
    fprintf(stderr, "replay_vectors: %s: %s\n", path, what);
    exit(2);
}

static const char *token(void) {
    char *start;
    while (*cursor == ' ' || *cursor == '\n' || *cursor == '\t' || *cursor == '\r') cursor++;
    if (*cursor == '\0') die("unexpected end of file");
    start = cursor;
    while (*cursor && *cursor != ' ' && *cursor != '\n' && *cursor != '\t' && *cursor != '\r') cursor++;
    if (*cursor) *cursor++ = '\0';
    return start;
}

/* whether the next token is `word` (not consumed) */
static int next_is(const char *word) {
    size_t n = strlen(word);
    while (*cursor == ' ' || *cursor == '\n' || *cursor == '\t' || *cursor == '\r') cursor++;
    return strncmp(cursor, word, n) == 0 && (cursor[n] == ' ' || cursor[n] == '\n' || cursor[n] == '\0');
}

static void expect(const char *word) {
    const char *t = token();
    if (strcmp(t, word) != 0) {
        fprintf(stderr, "replay_vectors: expected '%s', got '%s'\n", word, t);
        exit(2);
    }
}

static double number(void) {
    const char *t = token();
    char *end;
    double x = strtod(t, &end);
    if (*end != '\0') die("bad number");
    return x;
}

static size_t count(void) {
    const char *t = token();
    char *end;
    unsigned long long x = strtoull(t, &end, 10);
    if (*end != '\0') die("bad count");
    return (size_t)x;
}

static void *xmalloc(size_t n) {
    void *p = malloc(n ? n : 1);
    if (!p) die("out of memory");
    return p;
}

/* A model read from the file, with its buffers. */
typedef struct {
    PhsModelSpec spec;
    double *params;
    double *scratch;
    size_t n_scratch;
    PhsModel model;
} Loaded;

static void ok(PhsStatus s, const char *what, const char *name) {
    if (s != PHS_OK) {
        fprintf(stderr, "replay_vectors: %s: %s failed: %s (%s)\n", name, what, phs_status_name(s),
                phs_last_error_message());
        exit(1);
    }
}

static void load_model(Loaded *m, const char *name) {
    size_t i, n_dims;
    expect("model");
    memset(m, 0, sizeof *m);
    m->spec.family = (uint32_t)count();
    n_dims = count();
    if (n_dims > PHS_MAX_DIMS) die("too many dims");
    m->spec.n_dims = (uint32_t)n_dims;
    for (i = 0; i < n_dims; i++) m->spec.dims[i] = count();
    m->spec.n_params = count();
    m->params = xmalloc(m->spec.n_params * sizeof(double));
    for (i = 0; i < m->spec.n_params; i++) m->params[i] = number();
    m->spec.params = m->params;
    ok(phs_model_sizes(&m->spec, NULL, NULL, &m->n_scratch), "phs_model_sizes", name);
    m->scratch = xmalloc(m->n_scratch * sizeof(double));
    ok(phs_model_init(&m->model, &m->spec, m->n_scratch ? m->scratch : NULL, m->n_scratch), "phs_model_init", name);
}

static void free_model(Loaded *m) {
    free(m->params);
    free(m->scratch);
}

/* comparison bookkeeping */
static size_t values, identical, mismatches;
static double worst;

static void compare(const char *name, size_t k, double got, double want) {
    double diff = fabs(got - want), scale = fabs(want);
    values++;
    if (memcmp(&got, &want, sizeof got) == 0) {
        identical++;
        return;
    }
    if (scale > 0 && diff / scale > worst) worst = diff / scale;
    if (!(diff <= TOLERANCE * scale)) {
        if (mismatches < 10)
            fprintf(stderr, "replay_vectors: %s: sample %zu: C %.17g, Python %.17g (difference %.3g)\n", name, k, got,
                    want, diff);
        mismatches++;
    }
}

int main(int argc, char **argv) {
    FILE *f;
    long size;
    char *text;
    size_t n_forward = 0, n_inverse = 0, n_controller = 0;
    if (argc != 2) {
        fprintf(stderr, "usage: replay_vectors VECTORS.txt\n");
        return 2;
    }
    path = argv[1];
    f = fopen(path, "rb");
    if (!f) die("cannot open");
    fseek(f, 0, SEEK_END);
    size = ftell(f);
    fseek(f, 0, SEEK_SET);
    text = xmalloc((size_t)size + 1);
    if (fread(text, 1, (size_t)size, f) != (size_t)size) die("cannot read");
    text[size] = '\0';
    fclose(f);
    cursor = text;
    expect("piezohyst-vectors");
    if (count() != 1) die("unsupported version");

    for (;;) {
        const char *what = token();
        char name[128];
        if (strcmp(what, "end") == 0) break;
        snprintf(name, sizeof name, "%s %s", what, token());
        if (strcmp(what, "forward") == 0 || strcmp(what, "inverse") == 0) {
            int inverse = what[0] == 'i';
            Loaded m;
            size_t k, n;
            double *state, guess = 0.0;
            load_model(&m, name);
            state = xmalloc(m.model.state_len * sizeof(double));
            ok(phs_model_reset(&m.model, state, m.model.state_len), "phs_model_reset", name);
            expect("samples");
            n = count();
            for (k = 0; k < n; k++) {
                double in = number(), want = number(), got;
                if (inverse) {
                    ok(phs_model_inverse_step(&m.model, state, m.model.state_len, in, guess, &got), "phs_model_inverse_step",
                       name);
                    guess = got;
                } else {
                    ok(phs_model_step(&m.model, state, m.model.state_len, in, &got), "phs_model_step", name);
                }
                compare(name, k, got, want);
            }
            free(state);
            free_model(&m);
            if (inverse) n_inverse++; else n_forward++;
        } else if (strcmp(what, "controller") == 0) {
            uint32_t kind;
            size_t i, k, n, n_params, n_state;
            double *params, *state, y0;
            Loaded m;
            int has_inverse, has_ilc;
            PhsInverse inverse;
            PhsIlcSpec ilc;
            PhsController c;
            expect("kind");
            kind = (uint32_t)count();
            n_params = count();
            params = xmalloc(n_params * sizeof(double));
            for (i = 0; i < n_params; i++) params[i] = number();
            expect("inverse");
            if (next_is("none")) {
                token();
                has_inverse = 0;
            } else {
                has_inverse = 1;
                inverse.u_min = number();
                inverse.u_max = number();
                load_model(&m, name);
                inverse.model = &m.model;
            }
            expect("ilc");
            if (next_is("none")) {
                token();
                has_ilc = 0;
            } else {
                has_ilc = 1;
                ilc.period = count();
                ilc.gain = number();
                ilc.forgetting = number();
                ilc.lead = count();
                ilc.delay = count();
            }
            expect("y0");
            y0 = number();
            ok(phs_controller_init(&c, kind, params, n_params, has_inverse ? &inverse : NULL, has_ilc ? &ilc : NULL),
               "phs_controller_init", name);
            ok(phs_controller_state_len(&c, &n_state), "phs_controller_state_len", name);
            state = xmalloc(n_state * sizeof(double));
            ok(phs_controller_reset(&c, state, n_state, y0), "phs_controller_reset", name);
            expect("samples");
            n = count();
            for (k = 0; k < n; k++) {
                double x = number(), v = number(), a = number(), y = number(), want = number(), u;
                ok(phs_controller_step(&c, state, n_state, x, v, a, y, &u), "phs_controller_step", name);
                compare(name, k, u, want);
            }
            free(state);
            free(params);
            if (has_inverse) free_model(&m);
            n_controller++;
        } else {
            die("unknown case kind");
        }
    }
    free(text);
    printf("replay_vectors: %zu forward, %zu inverse, %zu controller cases; %zu values, %zu bit-identical, "
           "%zu beyond 1e-12; max relative difference %.3g\n",
           n_forward, n_inverse, n_controller, values, identical, mismatches, worst);
    return mismatches == 0 && values > 0 ? 0 : 1;
}
