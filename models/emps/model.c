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
 * which is (q0 - q2) / (2 h) at a constant step h. Fixed-step RK4 with `substeps` substeps.
 */
#include <math.h>

#include "command_delay.h"
#include "rk4.h"
#include "slave.h"

#define PI 3.14159265358979323846
#define RK4_STABILITY_MARGIN 2.0
#define TIME_TOLERANCE 1e-9      /* relative, for comparing command times with step ends */

enum { POSITION, SPEED, CARRIAGE, CARRIAGE_SPEED, STATE_COUNT };

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


/* Stick/slip transitions after a substep ending at time t (s); logged as events. */
static void update_friction_mode(const ModelInstance *inst, ModelState *s, double x[],
                                 double previous, double t) {
    const ModelVariables *v = &inst->v;
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
    if (previous * x[SPEED] <= 0.0 && breakaway(v, sign_of(drive)) > 0.0 &&
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

fmi2Status model_initialize(ModelInstance *inst) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double omega = 2.0 * PI * v->coupling_frequency;
    int i;
    if (v->second_mass >= v->mass) {
        slave_log_error(inst, "emps: second_mass %g kg must be below mass %g kg", v->second_mass, v->mass);
        return fmi2Error;
    }
    if (v->coulomb_friction - fabs(v->coulomb_asymmetry) < 0.0 ||
        v->viscous_friction - fabs(v->viscous_asymmetry) < 0.0) {
        slave_log_error(inst, "emps: the asymmetry makes a friction level negative (Fc %g N, a %g N; "
                        "Fv %g N.s/m, b %g N.s/m)", v->coulomb_friction, v->coulomb_asymmetry,
                        v->viscous_friction, v->viscous_asymmetry);
        return fmi2Error;
    }
    s->driven_mass = v->mass - v->second_mass;
    s->stiffness = v->second_mass * omega * omega;
    s->damping = 2.0 * v->coupling_damping * sqrt(s->stiffness * v->second_mass);
    s->position = s->carriage = v->load_position_start;
    s->speed = s->carriage_speed = 0.0;
    s->stuck = breakaway(v, 1.0) > 0.0 && breakaway(v, -1.0) > 0.0;
    s->direction = 0;
    command_delay_reset(&s->command, v->dead_time_steps * v->sample_period);
    for (i = 0; i < 3; i++) {
        s->encoder[i] = quantise(v, s->position);
        s->encoder_time[i] = i == 0 ? inst->start_time : NAN;   /* at rest before the start */
    }
    s->estimate = 0.0;
    slave_log_event(inst, "emps: substep limit %g s (RK4 margin %g over the %g rad/s coupling "
                    "mode); dead time %g s", RK4_STABILITY_MARGIN / coupling_mode(v, s),
                    RK4_STABILITY_MARGIN, coupling_mode(v, s), s->command.dead_time);
    return fmi2OK;
}

/* Integrates the state in `substeps` RK4 substeps over [start, start + length] (s) with the
 * drive command `command` (V) acting; a CommandSegment. */
static int integrate_segment(void *context, double command, double start, double length,
                             int substeps, int split) {
    ModelInstance *inst = (ModelInstance *)context;
    ModelState *s = &inst->s;
    double x[STATE_COUNT] = {s->position, s->speed, s->carriage, s->carriage_speed};
    double substep = length / substeps;
    int k;
    if (split) {
        slave_log_event(inst, "emps: t = %.9g s: the delayed drive command changes to %g V "
                        "inside the step", start, command);
    }
    for (k = 0; k < substeps; k++) {
        double previous = x[SPEED];
        rk4_step(derivatives, inst, x, STATE_COUNT, substep);
        update_friction_mode(inst, s, x, previous, start + (k + 1) * substep);
    }
    if (!isfinite(x[POSITION] + x[SPEED] + x[CARRIAGE] + x[CARRIAGE_SPEED])) {
        slave_log_error(inst, "emps: state became non-finite at t = %g s", start + length);
        return 0;
    }
    s->position = x[POSITION];
    s->speed = x[SPEED];
    s->carriage = x[CARRIAGE];
    s->carriage_speed = x[CARRIAGE_SPEED];
    return 1;
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

fmi2Status model_do_step(ModelInstance *inst, double t, double h) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double substep = h / v->substeps;
    double omega = coupling_mode(v, s);   /* rad/s */
    double tolerance = TIME_TOLERANCE * (h + fabs(t));   /* s */
    if (omega * substep > RK4_STABILITY_MARGIN) {
        slave_log_error(inst, "emps: substep %g s is too long for the %g rad/s coupling mode "
                        "(increase substeps)", substep, omega);
        return fmi2Error;
    }
    if (!command_delay_push(&s->command, t, v->current_cmd, tolerance)) {
        slave_log_error(inst, "emps: more than %d communication steps within the dead time of "
                        "%g s (use longer steps or a shorter dead time)", COMMAND_DELAY_CAPACITY,
                        s->command.dead_time);
        return fmi2Error;
    }
    if (!command_delay_advance(&s->command, t, h, v->substeps, tolerance, integrate_segment,
                               inst)) {
        return fmi2Error;
    }
    sample_encoder(v, s, t + h);
    return fmi2OK;
}

void model_update_outputs(ModelInstance *inst, double t) {
    ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    const double x[STATE_COUNT] = {s->position, s->speed, s->carriage, s->carriage_speed};
    (void)t;
    v->motor_angle = s->position / v->lead_per_rad;
    v->motor_speed = s->estimate / v->lead_per_rad;
    v->load_position = s->encoder[0];
    v->load_speed = s->speed;
    v->position_true = s->position;
    v->carriage_position = s->carriage;
    v->force = drive_force(v, s, s->position);
    v->friction_force = s->stuck ? driving_force(v, s, x) : sliding_friction(v, s, s->speed);
}
