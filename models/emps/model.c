/* emps: one-mass linear axis of the EMPS benchmark with optional effect blocks.
 *
 *   M1 dv/dt = g_tau u(k - n) - F_f(v) - offset - F_k - (F_d when rigid)
 *   M2 dv2/dt = F_k - F_d,   F_k = k (q - q2) + c (v - v2)          (only when second_mass > 0)
 *   F_f = (F_c + a s + F_x exp(-(v/v_s)^2)) s + (F_v + b s) v,   s = direction of sliding
 *
 * A force ripple A sin(order * motor_angle + phase) (cogging, eccentricity) adds to the drive
 * force when ripple_amplitude > 0. The driven mass sticks when its speed crosses zero and the
 * force driving it stays within the breakaway level F_c + a s + F_x. The drive command acts a
 * dead time T = dead_time_steps * sample_period late (in seconds, whatever the communication
 * step). The encoder quantises the driven mass' position; the controller's velocity estimate is
 * an output: the difference of the two-sample averages of the encoder position at the last three
 * communication points t0 > t1 > t2, over the time between the averages,
 *   v = ((q0 + q1)/2 - (q1 + q2)/2) / ((t0 + t1)/2 - (t1 + t2)/2) = (q0 - q2) / (t0 - t2),
 * which is (q0 - q2) / (2 h) at a constant step h. Fixed-step RK4 with `substeps` substeps in
 * the solver shared by the models (models/common/solver.h); the stick/slip mode is updated
 * between substeps (solver events).
 */
#include <math.h>

#include "slave.h"
#include "solver.h"

#define PI 3.14159265358979323846

enum { POSITION, SPEED, CARRIAGE, CARRIAGE_SPEED, STATE_COUNT };
SOLVER_CHECK_STATE_COUNT(STATE_COUNT);

static double sign_of(double x) { return (x > 0.0) - (x < 0.0); }

static int compliant(const ModelVariables *v) { return v->second_mass > 0.0; }

/* Coupling force on the second mass (N). */
static double coupling_force(const ModelState *s, const double x[]) {
    return s->stiffness * (x[POSITION] - x[CARRIAGE]) + s->damping * (x[SPEED] - x[CARRIAGE_SPEED]);
}

/* Drive force including the ripple of the motor angle (N). */
static double drive_force(const ModelVariables *v, const ModelState *s, double position) {
    double force = v->drive_gain * s->command.acting;
    if (v->ripple_amplitude > 0.0) {
        force += v->ripple_amplitude * sin(v->ripple_order * position / v->lead_per_rad + v->ripple_phase);
    }
    return force;
}

/* Force driving the driven mass apart from friction (N). */
static double driving_force(const ModelVariables *v, const ModelState *s, const double x[]) {
    double force = drive_force(v, s, x[POSITION]) - v->force_offset;
    return compliant(v) ? force - coupling_force(s, x) : force - v->disturbance_torque;
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
    double drive = driving_force(v, s, x);
    dx[POSITION] = s->stuck ? 0.0 : x[SPEED];
    dx[SPEED] = s->stuck ? 0.0 : (drive - sliding_friction(v, s, x[SPEED])) / s->driven_mass;
    if (compliant(v)) {
        dx[CARRIAGE] = x[CARRIAGE_SPEED];
        dx[CARRIAGE_SPEED] = (coupling_force(s, x) - v->disturbance_torque) / v->second_mass;
    } else {
        dx[CARRIAGE] = dx[POSITION];
        dx[CARRIAGE_SPEED] = dx[SPEED];
    }
}


/* Stick/slip transitions after a substep from `before` to x ending at time t (s), then the
 * sliding direction; the solver's events. Transitions are logged as events. */
static void update_friction_mode(ModelInstance *inst, const double before[], double x[],
                                 double t) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double drive = driving_force(v, s, x);
    if (s->stuck) {
        if (fabs(drive) > breakaway(v, sign_of(drive))) {
            s->stuck = 0;
            s->direction = (int)sign_of(drive);
            slave_log_event(inst, "emps: t = %.9g s: the axis breaks away (driving force %g N)",
                            t, drive);
        }
        return;
    }
    if (before[SPEED] * x[SPEED] <= 0.0 && breakaway(v, sign_of(drive)) > 0.0 &&
        fabs(drive) <= breakaway(v, sign_of(drive))) {
        s->stuck = 1;
        x[SPEED] = 0.0;
        if (!compliant(v)) x[CARRIAGE_SPEED] = 0.0;
        slave_log_event(inst, "emps: t = %.9g s: the axis sticks (driving force %g N)", t, drive);
        return;
    }
    if (x[SPEED] != 0.0) s->direction = (int)sign_of(x[SPEED]);
}

/* Natural frequency (rad/s) of the compliant coupling's mode, 0 for a rigid axis. */
static double coupling_mode(const ModelVariables *v, const ModelState *s) {
    if (!compliant(v)) return 0.0;
    return sqrt(s->stiffness / s->driven_mass + s->stiffness / v->second_mass);
}

static double quantise(const ModelVariables *v, double position) {
    return v->position_resolution > 0.0
               ? v->position_resolution * floor(position / v->position_resolution + 0.5)
               : position;
}

/* ---------------------------------------------------------------- the solver's table */

/* States RK4 integrates: all four (a rigid axis carries the second mass along). */
static int state_count(const ModelInstance *inst) {
    (void)inst;
    return STATE_COUNT;
}

/* The state into the solver's array and back: positions (m), speeds (m/s). */
static void load_state(const ModelInstance *inst, double x[]) {
    const ModelState *s = &inst->s;
    x[POSITION] = s->position;
    x[SPEED] = s->speed;
    x[CARRIAGE] = s->carriage;
    x[CARRIAGE_SPEED] = s->carriage_speed;
}

static void store_state(ModelInstance *inst, const double x[]) {
    ModelState *s = &inst->s;
    s->position = x[POSITION];
    s->speed = x[SPEED];
    s->carriage = x[CARRIAGE];
    s->carriage_speed = x[CARRIAGE_SPEED];
}

/* The rate that bounds the substep: the coupling mode (0 for a rigid axis). */
static int step_limits(const ModelInstance *inst, SolverLimit limit[]) {
    limit[0] = (SolverLimit){coupling_mode(&inst->v, &inst->s), "rad/s", "coupling mode"};
    return 1;
}

static const SolverModel kSolverModel = {
    .name = "emps",
    .command = "drive command",
    .command_unit = "V",
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
    double omega = 2.0 * PI * v->coupling_frequency;
    int i;
    if (v->second_mass >= v->mass) {
        slave_log_error(inst, "emps: second_mass %g kg must be below mass %g kg", v->second_mass, v->mass);
        return SLAVE_ERROR;
    }
    if (v->coulomb_friction - fabs(v->coulomb_asymmetry) < 0.0 ||
        v->viscous_friction - fabs(v->viscous_asymmetry) < 0.0) {
        slave_log_error(inst, "emps: the asymmetry makes a friction level negative (Fc %g N, a %g N; "
                        "Fv %g N.s/m, b %g N.s/m)", v->coulomb_friction, v->coulomb_asymmetry,
                        v->viscous_friction, v->viscous_asymmetry);
        return SLAVE_ERROR;
    }
    s->driven_mass = v->mass - v->second_mass;
    s->stiffness = v->second_mass * omega * omega;
    s->damping = 2.0 * v->coupling_damping * sqrt(s->stiffness * v->second_mass);
    s->position = s->carriage = v->load_position_start;
    s->speed = s->carriage_speed = 0.0;
    s->stuck = breakaway(v, 1.0) > 0.0 && breakaway(v, -1.0) > 0.0;
    s->direction = 0;
    for (i = 0; i < 3; i++) {
        s->encoder[i] = quantise(v, s->position);
        s->encoder_time[i] = i == 0 ? inst->start_time : NAN;   /* at rest before the start */
    }
    s->estimate = 0.0;
    solver_initialize(inst, &kSolverModel, &s->command, v->dead_time_steps * v->sample_period);
    return SLAVE_OK;
}

/* Samples the encoder at time t (s) and updates the velocity estimate (q0 - q2) / (t0 - t2). */
static void sample_encoder(const ModelVariables *v, ModelState *s, double t) {
    s->encoder[2] = s->encoder[1];
    s->encoder[1] = s->encoder[0];
    s->encoder[0] = quantise(v, s->position);
    s->encoder_time[2] = s->encoder_time[1];
    s->encoder_time[1] = s->encoder_time[0];
    s->encoder_time[0] = t;
    if (isnan(s->encoder_time[2])) {   /* first step: at rest one step before the start */
        s->encoder_time[2] = s->encoder_time[1] - (s->encoder_time[0] - s->encoder_time[1]);
    }
    s->estimate = (s->encoder[0] - s->encoder[2]) / (s->encoder_time[0] - s->encoder_time[2]);
}

SlaveStatus model_do_step(ModelInstance *inst, double t, double h) {
    if (solver_do_step(inst, &kSolverModel, &inst->s.command, t, h, inst->v.substeps,
                       inst->v.current_cmd) != SLAVE_OK) {
        return SLAVE_ERROR;
    }
    sample_encoder(&inst->v, &inst->s, t + h);
    return SLAVE_OK;
}

void model_update_outputs(ModelInstance *inst, double t) {
    ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    double x[STATE_COUNT];
    (void)t;
    load_state(inst, x);
    v->motor_angle = s->position / v->lead_per_rad;
    v->motor_speed = s->estimate / v->lead_per_rad;
    v->load_position = s->encoder[0];
    v->load_speed = s->speed;
    v->position_true = s->position;
    v->carriage_position = s->carriage;
    v->force = drive_force(v, s, s->position);
    v->friction_force = s->stuck ? driving_force(v, s, x) : sliding_friction(v, s, s->speed);
}
