/* The docs' C example (docs/guides/export_c.rst): a Prandtl–Ishlinskii model and its exact
 * per-sample inverse through libpiezohyst, as a real-time loop would run them. Nothing is
 * allocated: the model struct, its state and its parameter row are the caller's.
 *
 *   cc -std=c99 -O2 pi_inverse.c -I<dir of piezohyst.h> -L<dir of libpiezohyst> -lpiezohyst -lm
 *
 * It prints each sample and exits with 0 when the inverse gives back the input. */
#include <math.h>
#include <stdio.h>

#include "piezohyst.h"

int main(void) {
    /* piezohyst.PI(thresholds=[0.1, 0.3, 0.6], weights=[0.4, 0.2, 0.1], p0=1.0).to_row():
     * p0, r[3], w[3] (the layout table in piezohyst.h) */
    static const double row[7] = {1.0, 0.1, 0.3, 0.6, 0.4, 0.2, 0.1};
    PhsModelSpec spec = {PHS_FAMILY_PI, 2, {3, 0, 0, 0}, row, 7};
    PhsModel pi;
    double forward[8], inverse[8]; /* state buffers: phs_model_state_len says how many slots */
    size_t n_state = 0;

    if (phs_model_init(&pi, &spec, NULL, 0) != PHS_OK || phs_model_state_len(&pi, &n_state) != PHS_OK ||
        n_state > 8) {
        fprintf(stderr, "%s\n", phs_last_error_message()); /* names the argument and the value */
        return 1;
    }
    phs_model_reset(&pi, forward, n_state);
    phs_model_reset(&pi, inverse, n_state);

    static const double v[6] = {0.0, 0.5, 1.0, 0.7, 0.2, 0.6};
    double guess = 0.0, worst = 0.0;
    printf("libpiezohyst %s\n", phs_version());
    for (int k = 0; k < 6; ++k) {
        double y, v_back;
        /* the plant's side: the model's output for the input v[k] */
        if (phs_model_step(&pi, forward, n_state, v[k], &y) != PHS_OK) return 1;
        /* the compensator's side: the input that gives y, from the inverse's own state */
        if (phs_model_inverse_step(&pi, inverse, n_state, y, guess, &v_back) != PHS_OK) {
            fprintf(stderr, "%s\n", phs_last_error_message());
            return 1;
        }
        guess = v_back;
        printf("v = %.2f  y = %.4f  inverse(y) = %.4f\n", v[k], y, v_back);
        if (fabs(v_back - v[k]) > worst) worst = fabs(v_back - v[k]);
    }
    printf("largest |inverse(model(v)) - v| = %.3g\n", worst);
    return worst < 1e-12 ? 0 : 1;
}
