/* hsm150: the servo motor of the HSM150 bench as a rigid rotor with optional effect blocks.
 *
 *   J dw/dt = tau(i(t - T)) - F_f(w) - tau_d
 *   tau(i)  = K_t (1 + c sign i) i
 *   F_f     = (F_c + a s + F_x exp(-(w/w_s)^2)) s + (B + b s) w,   s = direction of sliding
 *
 * The rotor sticks when its speed crosses zero and the torque driving it stays within the
 * breakaway level F_c + a s + F_x, and breaks away when that torque exceeds it (no breakaway
 * level: pure viscous friction, the rotor never sticks). The current command acts a dead time
 * T = dead_time_steps * sample_period late (in seconds, whatever the communication step). The
 * encoder reads the angle on the grid angle_resolution; the drive's speed is the encoder's
 * difference over the last communication step, per its length. The rotor drives no carriage:
 * load_position and load_speed are the true angle and speed times travel_per_rad (a scale of
 * its own, not quantised by the encoder).
 * Fixed-step RK4 with `substeps` substeps in the solver shared by the models
 * (models/common/solver.h); the stick/slip mode is updated between substeps (solver events).
 */
#include <math.h>

#include "slave.h"
#include "solver.h"

enum { ANGLE, SPEED, STATE_COUNT };
SOLVER_CHECK_STATE_COUNT(STATE_COUNT);

static double sign_of(double x) { return (x > 0.0) - (x < 0.0); }

/* Drive torque of a current command (N.m). */
static double drive_torque(const ModelVariables *v, double current) {
    return v->torque_constant * (1.0 + v->torque_asymmetry * sign_of(current)) * current;
}

/* Torque driving the rotor apart from friction (N.m). */
static double driving_torque(const ModelVariables *v, const ModelState *s) {
    return drive_torque(v, s->command.acting) - v->disturbance_torque;
}

static double breakaway(const ModelVariables *v, double direction) {
    return v->coulomb_friction + v->coulomb_asymmetry * direction + v->stribeck_friction;
}

static double sliding_friction(const ModelVariables *v, const ModelState *s, double speed) {
    double d = (double)s->direction;
    double level = v->coulomb_friction + v->coulomb_asymmetry * d;
    if (v->stribeck_friction > 0.0) {
        double ratio = speed / v->stribeck_speed;
        level += v->stribeck_friction * exp(-ratio * ratio);
    }
    return level * d + (v->viscous_friction + v->viscous_asymmetry * d) * speed;
}

static void derivatives(const ModelInstance *inst, const double x[], double dx[]) {
    const ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    dx[ANGLE] = s->stuck ? 0.0 : x[SPEED];
    dx[SPEED] = s->stuck ? 0.0
                         : (driving_torque(v, s) - sliding_friction(v, s, x[SPEED])) / v->inertia;
}

/* Stick/slip transitions after a substep from `before` to x ending at time t (s), then the
 * sliding direction; the solver's events. Transitions are logged as events. */
static void update_friction_mode(ModelInstance *inst, const double before[], double x[],
                                 double t) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double drive = driving_torque(v, s);
    if (s->stuck) {
        if (fabs(drive) > breakaway(v, sign_of(drive))) {
            s->stuck = 0;
            s->direction = (int)sign_of(drive);
            slave_log_event(inst, "hsm150: t = %.9g s: the rotor breaks away (driving torque %g "
                            "N.m)", t, drive);
        }
        return;
    }
    if (before[SPEED] * x[SPEED] <= 0.0 && breakaway(v, sign_of(drive)) > 0.0 &&
        fabs(drive) <= breakaway(v, sign_of(drive))) {
        s->stuck = 1;
        x[SPEED] = 0.0;
        slave_log_event(inst, "hsm150: t = %.9g s: the rotor sticks (driving torque %g N.m)", t,
                        drive);
        return;
    }
    if (x[SPEED] != 0.0) s->direction = (int)sign_of(x[SPEED]);
}

static double quantise(const ModelVariables *v, double angle) {
    return v->angle_resolution > 0.0
               ? v->angle_resolution * floor(angle / v->angle_resolution + 0.5)
               : angle;
}

/* ---------------------------------------------------------------- the solver's table */

static int state_count(const ModelInstance *inst) {
    (void)inst;
    return STATE_COUNT;
}

/* The state into the solver's array and back: angle (rad), speed (rad/s). */
static void load_state(const ModelInstance *inst, double x[]) {
    x[ANGLE] = inst->s.angle;
    x[SPEED] = inst->s.speed;
}

static void store_state(ModelInstance *inst, const double x[]) {
    inst->s.angle = x[ANGLE];
    inst->s.speed = x[SPEED];
}

/* The rate that bounds the substep: the viscous decay rate (B + |b|) / J. */
static int step_limits(const ModelInstance *inst, SolverLimit limit[]) {
    const ModelVariables *v = &inst->v;
    double rate = (v->viscous_friction + fabs(v->viscous_asymmetry)) / v->inertia;
    limit[0] = (SolverLimit){rate, "1/s", "viscous decay"};
    return 1;
}

static const SolverModel kSolverModel = {
    .name = "hsm150",
    .command = "current command",
    .command_unit = "A",
    .state_count = state_count,
    .load_state = load_state,
    .store_state = store_state,
    .derivatives = derivatives,
    .events = update_friction_mode,
    .limits = step_limits,
};

SlaveStatus model_initialize(ModelInstance *inst) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    if (v->coulomb_friction - fabs(v->coulomb_asymmetry) < 0.0) {
        slave_log_error(inst, "hsm150: coulomb_asymmetry = %g is invalid (expected "
                        "|coulomb_asymmetry| <= coulomb_friction = %g)", v->coulomb_asymmetry,
                        v->coulomb_friction);
        return SLAVE_ERROR;
    }
    if (v->viscous_friction - fabs(v->viscous_asymmetry) < 0.0) {
        slave_log_error(inst, "hsm150: viscous_asymmetry = %g is invalid (expected "
                        "|viscous_asymmetry| <= viscous_friction = %g)", v->viscous_asymmetry,
                        v->viscous_friction);
        return SLAVE_ERROR;
    }
    s->angle = v->load_position_start / v->travel_per_rad;
    s->speed = 0.0;
    s->stuck = breakaway(v, 1.0) > 0.0 && breakaway(v, -1.0) > 0.0;
    s->direction = 0;
    s->encoder = quantise(v, s->angle);
    s->encoder_speed = 0.0;
    solver_initialize(inst, &kSolverModel, &s->command, v->dead_time_steps * v->sample_period);
    return SLAVE_OK;
}

SlaveStatus model_do_step(ModelInstance *inst, double t, double h) {
    ModelState *s = &inst->s;
    double previous = s->encoder;
    if (solver_do_step(inst, &kSolverModel, &s->command, t, h, inst->v.substeps,
                       inst->v.current_cmd) != SLAVE_OK) {
        return SLAVE_ERROR;
    }
    s->encoder = quantise(&inst->v, s->angle);
    s->encoder_speed = (s->encoder - previous) / h;
    return SLAVE_OK;
}

void model_update_outputs(ModelInstance *inst, double t) {
    ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    (void)t;
    v->motor_angle = s->encoder;
    v->motor_speed = s->encoder_speed;
    v->load_position = v->travel_per_rad * s->angle;
    v->load_speed = v->travel_per_rad * s->speed;
    v->rotor_angle = s->angle;
    v->rotor_speed = s->speed;
    v->torque = drive_torque(v, s->command.acting);
    v->friction_torque = s->stuck ? driving_torque(v, s) : sliding_friction(v, s, s->speed);
}
