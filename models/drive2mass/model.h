/* drive2mass: state of the two-mass feed axis. Variables live in the generated table. */
#ifndef MODEL_H
#define MODEL_H

#include "model_variables.h"

#define NOISE_HARMONICS 4

typedef struct {
    /* states, referred to the motor shaft */
    double motor_angle;         /* rad */
    double motor_speed;         /* rad/s */
    double load_angle;          /* rad */
    double load_speed;          /* rad/s */
    int stuck;                  /* 1 while static friction holds the load at rest */
    int direction;              /* hysteretic sign of the load speed seen by Coulomb friction */

    /* constants derived from the parameters by model_initialize */
    double stiffness;           /* N.m/rad, K = J_L omega_01^2 */
    double damping;             /* N.m.s/rad, B = 2 D_1 omega_01 J_L */
    double half_gap;            /* rad, half the backlash referred to the motor */
    double travel_per_rad;      /* m/rad, carriage travel per motor radian */
    double max_frequency;       /* rad/s, fastest natural frequency, for the step-size check */
    double noise_amplitude[NOISE_HARMONICS];    /* m */
    double noise_omega[NOISE_HARMONICS];        /* rad/s */
    double noise_phase[NOISE_HARMONICS];        /* rad */
} ModelState;

#endif
