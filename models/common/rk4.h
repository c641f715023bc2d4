/* One classical Runge-Kutta step, for the solver shared by the models (solver.h). Inlined where
 * it is used, so that the model's derivative function is called directly. */
#ifndef RK4_H
#define RK4_H

#define RK4_MAX_STATES 8

struct ModelInstance;

/* dx = f(x) for the model instance's current inputs and parameters. */
typedef void (*Derivatives)(const struct ModelInstance *inst, const double x[], double dx[]);

/* Advances the first n (<= RK4_MAX_STATES) entries of x by h (s); f must write dx[0..n-1].
 * The stages start zeroed: n is known at run time only, and an optimiser cannot see that f
 * writes them (without it, gcc -O3 warns -Wmaybe-uninitialized). A run-time n also keeps the
 * loops scalar, which measured faster here than fully unrolled vector loops over a constant n. */
static inline void rk4_step(Derivatives f, const struct ModelInstance *inst, double x[], int n,
                            double h) {
    double k1[RK4_MAX_STATES] = {0.0}, k2[RK4_MAX_STATES] = {0.0};
    double k3[RK4_MAX_STATES] = {0.0}, k4[RK4_MAX_STATES] = {0.0};
    double y[RK4_MAX_STATES] = {0.0};
    int i;
    f(inst, x, k1);
    for (i = 0; i < n; i++) y[i] = x[i] + 0.5 * h * k1[i];
    f(inst, y, k2);
    for (i = 0; i < n; i++) y[i] = x[i] + 0.5 * h * k2[i];
    f(inst, y, k3);
    for (i = 0; i < n; i++) y[i] = x[i] + h * k3[i];
    f(inst, y, k4);
    for (i = 0; i < n; i++) x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

#endif
