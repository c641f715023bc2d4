/* The fixed-step solver shared by the models: one communication step through the delayed
 * command, each segment of it in classical RK4 substeps with the model's events between them.
 *
 * A model describes itself in one constant table, SolverModel: the states it integrates, how
 * its state is copied into and out of an array, its derivatives, its events after a substep and
 * the rates that bound the substep. The solver owns the rest: the substep check, the command
 * delay, the substep loop, the RK4 steps (rk4.h) and the check that the state stays finite, each
 * failure logged under the model's name. Header-only, like rk4.h: inlined into model.c, where
 * the table is constant, so that the model's functions are called directly.
 */
#ifndef SOLVER_H
#define SOLVER_H

#include <math.h>
#include <string.h>

#include "command_delay.h"
#include "rk4.h"
#include "slave.h"

#define SOLVER_STABILITY_MARGIN 2.0 /* rate * substep below this keeps RK4 inside its limit 2.8 */
#define SOLVER_TIME_TOLERANCE 1e-9  /* relative, for comparing command times with step ends */
#define SOLVER_MAX_LIMITS 4         /* rates a model may bound the substep with */

/* Compiles only where a model's state count fits the solver's state arrays. */
#define SOLVER_CHECK_STATE_COUNT(count) \
    typedef char solver_state_count_fits[(count) <= RK4_MAX_STATES ? 1 : -1]

/* A rate of the model's dynamics: RK4 needs rate * substep <= SOLVER_STABILITY_MARGIN. */
typedef struct {
    double rate;        /* rad/s or 1/s, >= 0: a natural frequency or a real decay rate */
    const char *unit;   /* of the rate: "rad/s" or "1/s" */
    const char *what;   /* what has that rate, for messages: "coupling mode" */
} SolverLimit;

typedef struct {
    const char *name;           /* the model's name, first word of its messages */
    const char *command;        /* the delayed input, for messages: "current command" */
    const char *command_unit;   /* its unit: "A" */

    /* States RK4 integrates now: the first ones of the array, at most RK4_MAX_STATES. */
    int (*state_count)(const ModelInstance *inst);

    /* Copy the model's continuous state into x and back; x holds RK4_MAX_STATES entries and
     * the entries past state_count are carried over unchanged. */
    void (*load_state)(const ModelInstance *inst, double x[]);
    void (*store_state)(ModelInstance *inst, const double x[]);

    /* dx/dt with the discrete state and the acting command held (rk4.h). */
    Derivatives derivatives;

    /* Events after a substep from `before` to x, ending at time t (s): may change x (a mass
     * that sticks stops) and the discrete state, which then holds through the next substep. */
    void (*events)(ModelInstance *inst, const double before[], double x[], double t);

    /* Writes the rates that bound the substep in the present state into limit[]; returns how
     * many, 1 to SOLVER_MAX_LIMITS. */
    int (*limits)(const ModelInstance *inst, SolverLimit limit[]);
} SolverModel;

typedef struct {
    ModelInstance *inst;
    const SolverModel *model;
} SolverRun;

/* 1 when the first n states are finite: one isfinite over their sum, which is not finite when
 * one of them is not (or when they overflow together). */
static inline int solver_state_finite(const double x[], int n) {
    double sum = 0.0;
    int i;
    for (i = 0; i < n; i++) sum += x[i];
    return isfinite(sum);
}

/* The command delay reset for a dead time (s); logs the longest substep that the model's
 * fastest rate allows. Called once the model's derived constants are set. */
static inline void solver_initialize(const ModelInstance *inst, const SolverModel *model,
                                     CommandDelay *command, double dead_time) {
    SolverLimit limit[SOLVER_MAX_LIMITS];
    int count = model->limits(inst, limit);
    int fastest = 0, i;
    command_delay_reset(command, dead_time);
    for (i = 1; i < count; i++) {
        if (limit[i].rate > limit[fastest].rate) fastest = i;
    }
    slave_log_event(inst, "%s: substep limit %g s (RK4 margin %g over the %s, %g %s); dead time "
                    "%g s", model->name, SOLVER_STABILITY_MARGIN / limit[fastest].rate,
                    SOLVER_STABILITY_MARGIN, limit[fastest].what, limit[fastest].rate,
                    limit[fastest].unit, dead_time);
}

/* 1 when a substep (s) is stable for every rate of the model in the present state; else logs
 * the first rate it is too long for and returns 0. */
static inline int solver_substep_stable(const ModelInstance *inst, const SolverModel *model,
                                        double substep) {
    SolverLimit limit[SOLVER_MAX_LIMITS];
    int count = model->limits(inst, limit);
    int i;
    for (i = 0; i < count; i++) {
        if (limit[i].rate * substep > SOLVER_STABILITY_MARGIN) {
            slave_log_error(inst, "%s: substep %g s is too long for the %s (%g %s; RK4 needs at "
                            "most %g s: increase substeps)", model->name, substep, limit[i].what,
                            limit[i].rate, limit[i].unit, SOLVER_STABILITY_MARGIN / limit[i].rate);
            return 0;
        }
    }
    return 1;
}

/* Integrates [start, start + length] (s) in `substeps` RK4 substeps with `command` acting,
 * the model's events after each; a CommandSegment (context: a SolverRun). Returns 0, logged,
 * when the state becomes non-finite; the model's state then stays as it was. */
static inline int solver_segment(void *context, double command, double start, double length,
                                 int substeps, int split) {
    const SolverRun *run = (const SolverRun *)context;
    ModelInstance *inst = run->inst;
    const SolverModel *model = run->model;
    double x[RK4_MAX_STATES] = {0.0}, before[RK4_MAX_STATES];
    double substep = length / substeps;   /* s */
    int n = model->state_count(inst);
    int k;
    if (split) {
        slave_log_event(inst, "%s: t = %.9g s: the delayed %s changes to %g %s inside the step",
                        model->name, start, model->command, command, model->command_unit);
    }
    model->load_state(inst, x);
    for (k = 0; k < substeps; k++) {
        memcpy(before, x, sizeof(before));
        rk4_step(model->derivatives, inst, x, n, substep);
        model->events(inst, before, x, start + (k + 1) * substep);
    }
    if (!solver_state_finite(x, n)) {
        slave_log_error(inst, "%s: state became non-finite at t = %g s", model->name,
                        start + length);
        return 0;
    }
    model->store_state(inst, x);
    return 1;
}

/* Advances the model from t (s) by h (s) in substeps of at most h / substeps, `value` being the
 * command set at t: checks the substep against the model's rates, records the command behind
 * its dead time, then integrates the step segment by segment. Every failure is logged. */
static inline SlaveStatus solver_do_step(ModelInstance *inst, const SolverModel *model,
                                        CommandDelay *command, double t, double h, int substeps,
                                        double value) {
    SolverRun run = {inst, model};
    double substep = h / substeps;                              /* s */
    double tolerance = SOLVER_TIME_TOLERANCE * (h + fabs(t));   /* s */
    if (!solver_substep_stable(inst, model, substep)) return SLAVE_ERROR;
    if (!command_delay_push(command, t, value, tolerance)) {
        slave_log_error(inst, "%s: more than %d communication steps within the dead time of "
                        "%g s (use longer steps or a shorter dead time)", model->name,
                        COMMAND_DELAY_CAPACITY, command->dead_time);
        return SLAVE_ERROR;
    }
    if (!command_delay_advance(command, t, h, substeps, tolerance, solver_segment, &run)) {
        return SLAVE_ERROR;
    }
    return SLAVE_OK;
}

#endif
