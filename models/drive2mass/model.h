/* drive2mass: state of the two-mass feed axis. Variables live in the generated table. */
#ifndef MODEL_H
#define MODEL_H

#include "command_delay.h"
#include "model_variables.h"

/* The noise harmonics are the noise_amplitude_k / noise_frequency_k / noise_phase_k families
 * of variables.yaml: their count is the table's. */
#define NOISE_HARMONICS NOISE_AMPLITUDE_COUNT
#if NOISE_FREQUENCY_COUNT != NOISE_HARMONICS || NOISE_PHASE_COUNT != NOISE_HARMONICS
#error "variables.yaml: noise_amplitude_k, noise_frequency_k and noise_phase_k differ in number"
#endif
#define PITCH_HARMONICS PITCH_ERROR_AMPLITUDE_COUNT
#if PITCH_ERROR_PHASE_COUNT != PITCH_HARMONICS
#error "variables.yaml: pitch_error_amplitude_k and pitch_error_phase_k differ in number"
#endif

typedef struct {
    /* states, referred to the motor shaft */
    double motor_angle;         /* rad */
    double motor_speed;         /* rad/s */
    double load_angle;          /* rad */
    double load_speed;          /* rad/s */
    double current_applied;     /* A, current-loop output, a state while current_time_constant > 0 */
    double bristle;             /* rad, LuGre bristle deflection z, a state while lugre_stiffness > 0 */
    int stuck;                  /* 1 while static friction holds the load at rest */
    int direction;              /* hysteretic sign of the load speed seen by Coulomb friction */
    CommandDelay command;       /* A, current commands waiting out the dead time; `acting` is
                                   the one the drive acts on */

    /* constants derived from the parameters by model_initialize */
    double stiffness;           /* N.m/rad, K = J_L omega_01^2 */
    double damping;             /* N.m.s/rad, B = 2 D_1 omega_01 J_L */
    double half_gap;            /* rad, half the backlash referred to the motor */
    double travel_per_rad;      /* m/rad, carriage travel per motor radian */
    double max_frequency;       /* rad/s, fastest natural frequency, for the step-size check */
    double max_decay_rate;      /* 1/s, fastest real decay rate, for the step-size check */
    double lugre_level_min;     /* N.m, lowest LuGre friction level g, for the bristle-rate check */
    double start_load_angle;    /* rad, load angle at the start, where the transmission error is 0 */
    double pitch_error_start;   /* m, lead-error harmonics at the start screw angle */
    int transmission_error;     /* 1 when a lead error or thermal drift is set */
    double noise_amplitude[NOISE_HARMONICS];    /* m */
    double noise_omega[NOISE_HARMONICS];        /* rad/s */
    double noise_phase[NOISE_HARMONICS];        /* rad */
    double pitch_amplitude[PITCH_HARMONICS];    /* m */
    double pitch_phase[PITCH_HARMONICS];        /* rad */
} ModelState;

#endif
