/* drive2mass: two-mass feed axis with leadscrew backlash, friction and measurement noise.
 *
 *   J_M dw_M/dt = K_t i - M_S
 *   J_L dw_L/dt = M_S - M_F - M_D
 *   M_S = K dz(q_M - q_L) + B d(q_M - q_L)/dt   in contact, 0 inside the gap
 *
 * dz is the dead zone of half-width b; in contact the coupling can only push (M_S keeps the sign
 * of the penetration). M_F is Coulomb + viscous friction with a hysteretic sign and a stuck mode
 * that holds the load while the torque on it stays within the Coulomb level. Fixed-step RK4 with
 * `substeps` substeps per communication step; the friction mode is updated between substeps.
 * See README.md in this folder for the conversions from Table 1 of the paper.
 */
#include <math.h>

#include "slave.h"

#define PI 3.14159265358979323846
#define RK4_STABILITY_MARGIN 2.0 /* omega * h below this keeps RK4 well inside its limit 2.8 */

enum { MOTOR_ANGLE, MOTOR_SPEED, LOAD_ANGLE, LOAD_SPEED, STATE_COUNT };

static double sign_of(double x) { return (x > 0.0) - (x < 0.0); }

/* Coupling torque (N.m) for a twist (rad) and twist rate (rad/s). */
static double shaft_torque(const ModelState *s, double twist, double twist_rate) {
    double torque;
    if (s->half_gap == 0.0) return s->stiffness * twist + s->damping * twist_rate;
    if (twist > s->half_gap) {
        torque = s->stiffness * (twist - s->half_gap) + s->damping * twist_rate;
        return torque > 0.0 ? torque : 0.0;
    }
    if (twist < -s->half_gap) {
        torque = s->stiffness * (twist + s->half_gap) + s->damping * twist_rate;
        return torque < 0.0 ? torque : 0.0;
    }
    return 0.0;
}

static double sliding_friction(const ModelVariables *v, const ModelState *s, double load_speed) {
    return v->coulomb_friction * s->direction + v->viscous_friction * load_speed;
}

static void derivatives(const ModelVariables *v, const ModelState *s, const double x[],
                        double dx[]) {
    double coupling = shaft_torque(s, x[MOTOR_ANGLE] - x[LOAD_ANGLE],
                                   x[MOTOR_SPEED] - x[LOAD_SPEED]);
    dx[MOTOR_ANGLE] = x[MOTOR_SPEED];
    dx[MOTOR_SPEED] = (v->torque_constant * v->current_cmd - coupling) / v->motor_inertia;
    if (s->stuck) {
        dx[LOAD_ANGLE] = 0.0;
        dx[LOAD_SPEED] = 0.0;
    } else {
        dx[LOAD_ANGLE] = x[LOAD_SPEED];
        dx[LOAD_SPEED] = (coupling - sliding_friction(v, s, x[LOAD_SPEED]) -
                          v->disturbance_torque) / v->load_inertia;
    }
}

static void rk4_step(const ModelVariables *v, const ModelState *s, double x[], double h) {
    double k1[STATE_COUNT], k2[STATE_COUNT], k3[STATE_COUNT], k4[STATE_COUNT], y[STATE_COUNT];
    int i;
    derivatives(v, s, x, k1);
    for (i = 0; i < STATE_COUNT; i++) y[i] = x[i] + 0.5 * h * k1[i];
    derivatives(v, s, y, k2);
    for (i = 0; i < STATE_COUNT; i++) y[i] = x[i] + 0.5 * h * k2[i];
    derivatives(v, s, y, k3);
    for (i = 0; i < STATE_COUNT; i++) y[i] = x[i] + h * k3[i];
    derivatives(v, s, y, k4);
    for (i = 0; i < STATE_COUNT; i++) x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

/* Torque (N.m) that drives the load apart from friction. */
static double driving_torque(const ModelVariables *v, const ModelState *s, const double x[]) {
    return shaft_torque(s, x[MOTOR_ANGLE] - x[LOAD_ANGLE], x[MOTOR_SPEED] - x[LOAD_SPEED]) -
           v->disturbance_torque;
}

/* Stick/slip transitions after a substep, then the hysteresis relay on the load speed. */
static void update_friction_mode(const ModelVariables *v, ModelState *s, double x[],
                                 double previous_load_speed) {
    double drive = driving_torque(v, s, x);
    if (s->stuck) {
        if (fabs(drive) > v->coulomb_friction) {
            s->stuck = 0;
            s->direction = (int)sign_of(drive);
        }
        return;
    }
    if (v->coulomb_friction > 0.0 && previous_load_speed * x[LOAD_SPEED] <= 0.0 &&
        fabs(drive) <= v->coulomb_friction) {
        s->stuck = 1;
        x[LOAD_SPEED] = 0.0;
        return;
    }
    if (x[LOAD_SPEED] > 0.5 * v->friction_hysteresis) s->direction = 1;
    if (x[LOAD_SPEED] < -0.5 * v->friction_hysteresis) s->direction = -1;
}

fmi2Status model_initialize(ModelInstance *inst) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double omega_01 = 2.0 * PI * v->resonance_frequency;
    const double amplitude[NOISE_HARMONICS] = {v->noise_amplitude_1, v->noise_amplitude_2,
                                               v->noise_amplitude_3, v->noise_amplitude_4};
    const double frequency[NOISE_HARMONICS] = {v->noise_frequency_1, v->noise_frequency_2,
                                               v->noise_frequency_3, v->noise_frequency_4};
    const double phase[NOISE_HARMONICS] = {v->noise_phase_1, v->noise_phase_2, v->noise_phase_3,
                                           v->noise_phase_4};
    int k;

    s->stiffness = v->load_inertia * omega_01 * omega_01;
    s->damping = 2.0 * v->damping_ratio * omega_01 * v->load_inertia;
    s->travel_per_rad = v->spindle_constant / v->gear_ratio;
    s->half_gap = 0.5 * v->backlash / s->travel_per_rad;
    /* omega_02 = omega_01 sqrt(1 + J_L/J_M), eq. (1); the damped pair's modulus is the same. */
    s->max_frequency = omega_01 * sqrt(1.0 + v->load_inertia / v->motor_inertia);
    for (k = 0; k < NOISE_HARMONICS; k++) {
        s->noise_amplitude[k] = amplitude[k];
        s->noise_omega[k] = 2.0 * PI * frequency[k];
        s->noise_phase[k] = phase[k];
    }
    s->load_angle = v->load_position_start / s->travel_per_rad;
    s->motor_angle = s->load_angle;
    s->motor_speed = 0.0;
    s->load_speed = 0.0;
    s->stuck = v->coulomb_friction > 0.0;
    s->direction = 0;
    if (!isfinite(s->load_angle) || !isfinite(s->half_gap) || !isfinite(s->stiffness)) {
        slave_log_error(inst, "drive2mass: parameters give a non-finite initial state");
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status model_do_step(ModelInstance *inst, double t, double h) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double x[STATE_COUNT] = {s->motor_angle, s->motor_speed, s->load_angle, s->load_speed};
    double substep = h / v->substeps;
    double damping_rate = s->damping * (1.0 / v->motor_inertia + 1.0 / v->load_inertia);
    int k;
    (void)t;
    if (s->max_frequency * substep > RK4_STABILITY_MARGIN ||
        damping_rate * substep > RK4_STABILITY_MARGIN) {
        slave_log_error(inst, "drive2mass: substep %g s is too long for the %g rad/s mode "
                        "(increase substeps)", substep, s->max_frequency);
        return fmi2Error;
    }
    for (k = 0; k < v->substeps; k++) {
        double previous_load_speed = x[LOAD_SPEED];
        rk4_step(v, s, x, substep);
        update_friction_mode(v, s, x, previous_load_speed);
    }
    if (!isfinite(x[MOTOR_ANGLE] + x[MOTOR_SPEED] + x[LOAD_ANGLE] + x[LOAD_SPEED])) {
        slave_log_error(inst, "drive2mass: state became non-finite at t = %g s", t + h);
        return fmi2Error;
    }
    s->motor_angle = x[MOTOR_ANGLE];
    s->motor_speed = x[MOTOR_SPEED];
    s->load_angle = x[LOAD_ANGLE];
    s->load_speed = x[LOAD_SPEED];
    return fmi2OK;
}

void model_update_outputs(ModelInstance *inst, double t) {
    ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    const double x[STATE_COUNT] = {s->motor_angle, s->motor_speed, s->load_angle, s->load_speed};
    double noise = 0.0;
    int k;
    for (k = 0; k < NOISE_HARMONICS; k++) {
        noise += s->noise_amplitude[k] * sin(s->noise_omega[k] * t + s->noise_phase[k]);
    }
    v->motor_angle = s->motor_angle;
    v->motor_speed = s->motor_speed;
    v->load_position_true = s->load_angle * s->travel_per_rad;
    v->load_position = v->load_position_true + noise;
    v->load_speed = s->load_speed * s->travel_per_rad;
    v->shaft_torque = shaft_torque(s, x[MOTOR_ANGLE] - x[LOAD_ANGLE],
                                   x[MOTOR_SPEED] - x[LOAD_SPEED]);
    v->motor_torque = v->torque_constant * v->current_cmd;
    v->friction_torque = s->stuck ? driving_torque(v, s, x) : sliding_friction(v, s, s->load_speed);
}
