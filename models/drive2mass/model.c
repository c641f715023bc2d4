/* drive2mass: two-mass feed axis with leadscrew backlash, friction and measurement noise.
 *
 *   J_M dw_M/dt = M_M - M_S,   M_M = K_t i_a (+ torque ripple)
 *   J_L dw_L/dt = M_S - M_F - M_D
 *   M_S = K dz(q_M - q_L) + B d(q_M - q_L)/dt   in contact, 0 inside the gap
 *
 * dz is the dead zone of half-width b; in contact the coupling can only push (M_S keeps the sign
 * of the penetration). M_F is Coulomb + viscous friction with a hysteretic sign and a stuck mode
 * that holds the load while the torque on it stays within the static level. Fixed-step RK4 with
 * `substeps` substeps per communication step in the solver shared by the models
 * (models/common/solver.h); the friction mode is updated between substeps (solver events).
 *
 * Effect blocks, all off by default: Stribeck, asymmetric and position-dependent friction levels,
 * LuGre friction (state z), lead error, thermal drift, scale quantisation, torque ripple, current
 * lag (state i_a) and dead time of the current command (dead_time_steps sample periods, in
 * seconds whatever the communication step). Each is skipped while its parameter is zero, so
 * that the default model computes exactly what it computes without them.
 * See README.md in this folder for the equations and the conversions from Table 1 of the paper.
 */
#include <math.h>

#include "slave.h"
#include "solver.h"

#define PI 3.14159265358979323846

enum {
    MOTOR_ANGLE, MOTOR_SPEED, LOAD_ANGLE, LOAD_SPEED,  /* always integrated */
    CURRENT_APPLIED, BRISTLE,                          /* only with current lag or LuGre friction */
    STATE_COUNT
};
enum { MECHANICAL_STATE_COUNT = CURRENT_APPLIED };
SOLVER_CHECK_STATE_COUNT(STATE_COUNT);

static double sign_of(double x) { return (x > 0.0) - (x < 0.0); }

/* Carriage travel per motor radian (m/rad): spindle constant over gear ratio (the model card
 * states the same for the Python side). */
static double travel_per_rad(const ModelVariables *v) { return v->spindle_constant / v->gear_ratio; }

/* Leadscrew angle (rad) of a load angle referred to the motor (rad). */
static double screw_angle(const ModelVariables *v, double load_angle) {
    return load_angle / v->gear_ratio;
}

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

/* Motor torque (N.m) for an applied current (A) at a motor angle (rad): K_t i_a plus ripple. */
static double motor_torque(const ModelVariables *v, double current, double motor_angle) {
    double torque = v->torque_constant * current;
    if (v->ripple_amplitude == 0.0) return torque;
    return torque + v->ripple_amplitude * sin(v->ripple_order * motor_angle + v->ripple_phase);
}

/* Factor (1) on the friction levels at a load angle (rad): 1 + a cos(k theta_screw + phi). */
static double friction_position_factor(const ModelVariables *v, double load_angle) {
    if (v->position_friction_amplitude == 0.0) return 1.0;
    return 1.0 + v->position_friction_amplitude *
                     cos(v->position_friction_order * screw_angle(v, load_angle) +
                         v->position_friction_phase);
}

/* Breakaway level (N.m) for a driving torque of sign `direction` at a load angle (rad). */
static double static_friction(const ModelVariables *v, double direction, double load_angle) {
    return (v->coulomb_friction + v->coulomb_asymmetry * direction + v->stribeck_friction) *
           friction_position_factor(v, load_angle);
}

/* Sliding friction level g (N.m) for motion of sign `direction` at a load speed (rad/s) and
 * angle (rad): (F_C + a direction + F_x exp(-(w_L/v_s)^2)) times the position factor. */
static double friction_level(const ModelVariables *v, double direction, double load_speed,
                             double load_angle) {
    double level = v->coulomb_friction + v->coulomb_asymmetry * direction;
    if (v->stribeck_friction != 0.0) {
        double ratio = load_speed / v->stribeck_speed;   /* 1 */
        level += v->stribeck_friction * exp(-ratio * ratio);
    }
    return level * friction_position_factor(v, load_angle);
}

/* Friction torque (N.m) while sliding at a load speed (rad/s) and angle (rad). */
static double sliding_friction(const ModelVariables *v, const ModelState *s, double load_speed,
                               double load_angle) {
    return friction_level(v, s->direction, load_speed, load_angle) * s->direction +
           v->viscous_friction * load_speed;
}

/* LuGre bristle rate dz/dt (rad/s) = w_L - sigma_0 |w_L| z / g(w_L), for a load speed (rad/s),
 * load angle (rad) and bristle deflection z (rad). */
static double bristle_rate(const ModelVariables *v, double load_speed, double load_angle,
                           double bristle) {
    double level = friction_level(v, sign_of(load_speed), load_speed, load_angle);
    return load_speed - v->lugre_stiffness * fabs(load_speed) * bristle / level;
}

/* LuGre friction torque (N.m) = sigma_0 z + sigma_1 dz/dt + F_V w_L. */
static double lugre_friction(const ModelVariables *v, double load_speed, double bristle,
                             double rate) {
    return v->lugre_stiffness * bristle + v->lugre_damping * rate +
           v->viscous_friction * load_speed;
}

/* Derivatives of the load angle, load speed and bristle deflection for a coupling torque (N.m). */
static void load_derivatives(const ModelVariables *v, const ModelState *s, const double x[],
                             double coupling, double dx[]) {
    dx[BRISTLE] = 0.0;
    if (v->lugre_stiffness > 0.0) {
        dx[BRISTLE] = bristle_rate(v, x[LOAD_SPEED], x[LOAD_ANGLE], x[BRISTLE]);
        dx[LOAD_ANGLE] = x[LOAD_SPEED];
        dx[LOAD_SPEED] = (coupling - lugre_friction(v, x[LOAD_SPEED], x[BRISTLE], dx[BRISTLE]) -
                          v->disturbance_torque) / v->load_inertia;
    } else if (s->stuck) {
        dx[LOAD_ANGLE] = 0.0;
        dx[LOAD_SPEED] = 0.0;
    } else {
        dx[LOAD_ANGLE] = x[LOAD_SPEED];
        dx[LOAD_SPEED] = (coupling - sliding_friction(v, s, x[LOAD_SPEED], x[LOAD_ANGLE]) -
                          v->disturbance_torque) / v->load_inertia;
    }
}

static void derivatives(const ModelInstance *inst, const double x[], double dx[]) {
    const ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    double coupling = shaft_torque(s, x[MOTOR_ANGLE] - x[LOAD_ANGLE],
                                   x[MOTOR_SPEED] - x[LOAD_SPEED]);
    double lag = v->current_time_constant;   /* s */
    double current = lag > 0.0 ? x[CURRENT_APPLIED] : s->command.acting;   /* A */
    dx[MOTOR_ANGLE] = x[MOTOR_SPEED];
    dx[MOTOR_SPEED] = (motor_torque(v, current, x[MOTOR_ANGLE]) - coupling) / v->motor_inertia;
    dx[CURRENT_APPLIED] = lag > 0.0 ? (s->command.acting - x[CURRENT_APPLIED]) / lag : 0.0;
    load_derivatives(v, s, x, coupling, dx);
}


/* Torque (N.m) that drives the load apart from friction. */
static double driving_torque(const ModelVariables *v, const ModelState *s, const double x[]) {
    return shaft_torque(s, x[MOTOR_ANGLE] - x[LOAD_ANGLE], x[MOTOR_SPEED] - x[LOAD_SPEED]) -
           v->disturbance_torque;
}

/* Stick/slip transitions after a substep from `before` to x ending at time t (s), then the
 * hysteresis relay on the load speed; the solver's events. Transitions are logged as events.
 * LuGre friction, when on, replaces all of it. */
static void update_friction_mode(ModelInstance *inst, const double before[], double x[],
                                 double t) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double drive;
    if (v->lugre_stiffness > 0.0) return;
    drive = driving_torque(v, s, x);
    if (s->stuck) {
        if (drive > static_friction(v, 1.0, x[LOAD_ANGLE]) ||
            -drive > static_friction(v, -1.0, x[LOAD_ANGLE])) {
            s->stuck = 0;
            s->direction = (int)sign_of(drive);
            slave_log_event(inst, "drive2mass: t = %.9g s: the load breaks away (driving torque "
                            "%g N.m)", t, drive);
        }
        return;
    }
    if (v->coulomb_friction + v->stribeck_friction > 0.0 &&
        before[LOAD_SPEED] * x[LOAD_SPEED] <= 0.0 &&
        drive <= static_friction(v, 1.0, x[LOAD_ANGLE]) &&
        -drive <= static_friction(v, -1.0, x[LOAD_ANGLE])) {
        s->stuck = 1;
        x[LOAD_SPEED] = 0.0;
        slave_log_event(inst, "drive2mass: t = %.9g s: the load sticks (driving torque %g N.m)",
                        t, drive);
        return;
    }
    if (x[LOAD_SPEED] > 0.5 * v->friction_hysteresis) s->direction = 1;
    if (x[LOAD_SPEED] < -0.5 * v->friction_hysteresis) s->direction = -1;
}

/* Friction torque (N.m) on the load in the current state. */
static double friction_torque(const ModelVariables *v, const ModelState *s, const double x[]) {
    if (v->lugre_stiffness > 0.0) {
        return lugre_friction(v, x[LOAD_SPEED], x[BRISTLE],
                              bristle_rate(v, x[LOAD_SPEED], x[LOAD_ANGLE], x[BRISTLE]));
    }
    if (s->stuck) return driving_torque(v, s, x);
    return sliding_friction(v, s, x[LOAD_SPEED], x[LOAD_ANGLE]);
}

/* Current (A) that produces the motor torque: the current-loop state with a lag, else the
 * command of the last step after the dead time (current_cmd itself without dead time). */
static double applied_current(const ModelVariables *v, const ModelState *s) {
    if (v->current_time_constant > 0.0) return s->current_applied;
    return s->command.dead_time > 0.0 ? s->command.acting : v->current_cmd;
}

/* Lead-error harmonics (m) at a screw angle (rad): sum_k e_k sin(k theta_screw + phi_k). */
static double pitch_harmonics(const ModelState *s, double screw_angle) {
    double error = 0.0;
    int k;
    for (k = 0; k < PITCH_HARMONICS; k++) {
        if (s->pitch_amplitude[k] == 0.0) continue;
        error += s->pitch_amplitude[k] * sin((k + 1) * screw_angle + s->pitch_phase[k]);
    }
    return error;
}

/* Slope (m/rad) of pitch_harmonics with respect to the screw angle (rad). */
static double pitch_harmonics_slope(const ModelState *s, double screw_angle) {
    double slope = 0.0;
    int k;
    for (k = 0; k < PITCH_HARMONICS; k++) {
        if (s->pitch_amplitude[k] == 0.0) continue;
        slope += (k + 1) * s->pitch_amplitude[k] * cos((k + 1) * screw_angle + s->pitch_phase[k]);
    }
    return slope;
}

/* Relative error (1) of the travel per radian at time t (s): (1 + c)(1 + rate t) - 1. */
static double scale_error(const ModelVariables *v, double t) {
    return v->pitch_error_linear + v->thermal_expansion_rate * t * (1.0 + v->pitch_error_linear);
}

/* Carriage position error (m) at time t (s) from the lead error and thermal drift; zero at the
 * start: travel (q_L - q_L0) scale_error(t) + E(theta_screw) - E(theta_screw0). */
static double transmission_error(const ModelVariables *v, const ModelState *s, double t) {
    return s->travel_per_rad * (s->load_angle - s->start_load_angle) * scale_error(v, t) +
           pitch_harmonics(s, screw_angle(v, s->load_angle)) - s->pitch_error_start;
}

/* Time derivative (m/s) of transmission_error at time t (s). */
static double transmission_error_rate(const ModelVariables *v, const ModelState *s, double t) {
    double scale_rate = v->thermal_expansion_rate * (1.0 + v->pitch_error_linear);   /* 1/s */
    return s->travel_per_rad * (s->load_speed * scale_error(v, t) +
                                (s->load_angle - s->start_load_angle) * scale_rate) +
           pitch_harmonics_slope(s, screw_angle(v, s->load_angle)) * s->load_speed / v->gear_ratio;
}

/* The linear scale's reading (m) of a position (m): quantised to position_resolution when set. */
static double scale_reading(const ModelVariables *v, double position) {
    if (v->position_resolution == 0.0) return position;
    return v->position_resolution * round(position / v->position_resolution);
}

/* ---------------------------------------------------------------- the solver's table */

/* States RK4 integrates: the mechanics, and i_a and z while current lag or LuGre is on. */
static int state_count(const ModelInstance *inst) {
    const ModelVariables *v = &inst->v;
    return v->current_time_constant > 0.0 || v->lugre_stiffness > 0.0 ? STATE_COUNT
                                                                        : MECHANICAL_STATE_COUNT;
}

/* The state into the solver's array and back: angles (rad), speeds (rad/s), i_a (A), z (rad). */
static void load_state(const ModelInstance *inst, double x[]) {
    const ModelState *s = &inst->s;
    x[MOTOR_ANGLE] = s->motor_angle;
    x[MOTOR_SPEED] = s->motor_speed;
    x[LOAD_ANGLE] = s->load_angle;
    x[LOAD_SPEED] = s->load_speed;
    x[CURRENT_APPLIED] = s->current_applied;
    x[BRISTLE] = s->bristle;
}

static void store_state(ModelInstance *inst, const double x[]) {
    ModelState *s = &inst->s;
    s->motor_angle = x[MOTOR_ANGLE];
    s->motor_speed = x[MOTOR_SPEED];
    s->load_angle = x[LOAD_ANGLE];
    s->load_speed = x[LOAD_SPEED];
    s->current_applied = x[CURRENT_APPLIED];
    s->bristle = x[BRISTLE];
}

/* Fastest relaxation rate (1/s) of the LuGre bristles at the present load speed. */
static double bristle_relaxation_rate(const ModelVariables *v, const ModelState *s) {
    return v->lugre_stiffness * fabs(s->load_speed) / s->lugre_level_min;
}

/* Rates that bound the substep: the fastest mode and decay, and the LuGre bristles' relaxation
 * at the present load speed while LuGre is on. */
static int step_limits(const ModelInstance *inst, SolverLimit limit[]) {
    const ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    limit[0] = (SolverLimit){s->max_frequency, "rad/s", "fastest mode"};
    limit[1] = (SolverLimit){s->max_decay_rate, "1/s", "fastest decay"};
    if (v->lugre_stiffness == 0.0) return 2;
    limit[2] = (SolverLimit){bristle_relaxation_rate(v, s), "1/s",
                             "LuGre bristles at the present load speed"};
    return 3;
}

static const SolverModel kSolverModel = {
    .name = "drive2mass",
    .command = "current command",
    .command_unit = "A",
    .state_count = state_count,
    .load_state = load_state,
    .store_state = store_state,
    .derivatives = derivatives,
    .events = update_friction_mode,
    .limits = step_limits,
};

/* Checks the effect parameters against each other and against the dead-time buffer. */
static SlaveStatus check_effect_parameters(ModelInstance *inst) {
    const ModelVariables *v = &inst->v;
    double lowest_coulomb = v->coulomb_friction - fabs(v->coulomb_asymmetry);   /* N.m */
    if (lowest_coulomb < 0.0) {
        slave_log_error(inst, "drive2mass: coulomb_asymmetry = %g is invalid (expected "
                        "|coulomb_asymmetry| <= coulomb_friction = %g)", v->coulomb_asymmetry,
                        v->coulomb_friction);
        return SLAVE_ERROR;
    }
    if (v->lugre_stiffness > 0.0 && !(lowest_coulomb > 0.0)) {
        slave_log_error(inst, "drive2mass: lugre_stiffness = %g needs a positive Coulomb level in "
                        "both directions (coulomb_friction - |coulomb_asymmetry| = %g)",
                        v->lugre_stiffness, lowest_coulomb);
        return SLAVE_ERROR;
    }
    return SLAVE_OK;
}

/* Step-size limits of the effect-extended model: fastest natural frequency and decay rate. */
static void derive_step_limits(const ModelVariables *v, ModelState *s, double omega_02) {
    s->max_frequency = sqrt(omega_02 * omega_02 + v->lugre_stiffness / v->load_inertia);
    s->max_decay_rate = s->damping * (1.0 / v->motor_inertia + 1.0 / v->load_inertia) +
                        v->lugre_damping / v->load_inertia;
    if (v->current_time_constant > 0.0 && 1.0 / v->current_time_constant > s->max_decay_rate) {
        s->max_decay_rate = 1.0 / v->current_time_constant;
    }
    s->lugre_level_min = (v->coulomb_friction - fabs(v->coulomb_asymmetry)) *
                         (1.0 - v->position_friction_amplitude);
}

/* Lead-error harmonics and the flag that switches the transmission error on. */
static void derive_transmission(const ModelVariables *v, ModelState *s) {
    int k;
    s->transmission_error = v->pitch_error_linear != 0.0 || v->thermal_expansion_rate != 0.0;
    for (k = 0; k < PITCH_HARMONICS; k++) {
        s->pitch_amplitude[k] = MODEL_FAMILY_VALUE(v, kPitchErrorAmplitude, k);
        s->pitch_phase[k] = MODEL_FAMILY_VALUE(v, kPitchErrorPhase, k);
        if (s->pitch_amplitude[k] != 0.0) s->transmission_error = 1;
    }
    s->start_load_angle = s->load_angle;
    s->pitch_error_start = pitch_harmonics(s, screw_angle(v, s->load_angle));
}

SlaveStatus model_initialize(ModelInstance *inst) {
    const ModelVariables *v = &inst->v;
    ModelState *s = &inst->s;
    double omega_01 = 2.0 * PI * v->resonance_frequency;
    int k;

    if (check_effect_parameters(inst) != SLAVE_OK) return SLAVE_ERROR;
    s->stiffness = v->load_inertia * omega_01 * omega_01;
    s->damping = 2.0 * v->damping_ratio * omega_01 * v->load_inertia;
    s->travel_per_rad = travel_per_rad(v);
    s->half_gap = 0.5 * v->backlash / s->travel_per_rad;
    /* omega_02 = omega_01 sqrt(1 + J_L/J_M), eq. (1); the damped pair's modulus is the same. */
    derive_step_limits(v, s, omega_01 * sqrt(1.0 + v->load_inertia / v->motor_inertia));
    for (k = 0; k < NOISE_HARMONICS; k++) {
        s->noise_amplitude[k] = MODEL_FAMILY_VALUE(v, kNoiseAmplitude, k);
        s->noise_omega[k] = 2.0 * PI * MODEL_FAMILY_VALUE(v, kNoiseFrequency, k);
        s->noise_phase[k] = MODEL_FAMILY_VALUE(v, kNoisePhase, k);
    }
    s->load_angle = v->load_position_start / s->travel_per_rad;
    s->motor_angle = s->load_angle;
    s->motor_speed = 0.0;
    s->load_speed = 0.0;
    s->current_applied = 0.0;
    s->bristle = 0.0;
    s->stuck = v->coulomb_friction + v->stribeck_friction > 0.0 && v->lugre_stiffness == 0.0;
    s->direction = 0;
    derive_transmission(v, s);
    if (!isfinite(s->load_angle) || !isfinite(s->half_gap) || !isfinite(s->stiffness) ||
        !isfinite(s->pitch_error_start)) {
        slave_log_error(inst, "drive2mass: parameters give a non-finite initial state");
        return SLAVE_ERROR;
    }
    solver_initialize(inst, &kSolverModel, &s->command, v->dead_time_steps * v->sample_period);
    return SLAVE_OK;
}

SlaveStatus model_do_step(ModelInstance *inst, double t, double h) {
    return solver_do_step(inst, &kSolverModel, &inst->s.command, t, h, inst->v.substeps,
                          inst->v.current_cmd);
}

void model_update_outputs(ModelInstance *inst, double t) {
    ModelVariables *v = &inst->v;
    const ModelState *s = &inst->s;
    double x[STATE_COUNT];
    double current = applied_current(v, s);   /* A */
    double noise = 0.0;
    int k;
    load_state(inst, x);
    for (k = 0; k < NOISE_HARMONICS; k++) {
        if (s->noise_amplitude[k] == 0.0) continue;   /* adds +-0: the sum is the same */
        noise += s->noise_amplitude[k] * sin(s->noise_omega[k] * t + s->noise_phase[k]);
    }
    v->motor_angle = s->motor_angle;
    v->motor_speed = s->motor_speed;
    v->load_position_true = s->load_angle * s->travel_per_rad;
    v->load_speed = s->load_speed * s->travel_per_rad;
    if (s->transmission_error) {
        v->load_position_true += transmission_error(v, s, t);
        v->load_speed += transmission_error_rate(v, s, t);
    }
    v->load_position = scale_reading(v, v->load_position_true + noise);
    v->shaft_torque = shaft_torque(s, x[MOTOR_ANGLE] - x[LOAD_ANGLE],
                                   x[MOTOR_SPEED] - x[LOAD_SPEED]);
    v->motor_torque = motor_torque(v, current, s->motor_angle);
    v->friction_torque = friction_torque(v, s, x);
    v->load_angle = s->load_angle;
    v->current_applied = current;
}
