/* emps: state of the linear axis of the EMPS benchmark. Variables live in the generated table. */
#ifndef MODEL_H
#define MODEL_H

#include "command_delay.h"
#include "model_variables.h"

typedef struct {
    /* states */
    double position;            /* m, driven mass (motor side, measured by the encoder) */
    double speed;               /* m/s */
    double carriage;            /* m, second mass behind the coupling */
    double carriage_speed;      /* m/s */
    int stuck;                  /* 1 while static friction holds the driven mass */
    int direction;              /* sign of the sliding speed seen by Coulomb friction */

    /* discrete states of the drive and the velocity estimate */
    CommandDelay command;               /* V, drive commands waiting out the dead time;
                                           `acting` is the one acting now */
    double encoder[3];                  /* m, encoder positions at the last three points */
    double encoder_time[3];             /* s, times of those points */
    double estimate;                    /* m/s, velocity estimate at the last point */

    /* constants derived from the parameters by model_initialize */
    double driven_mass;         /* kg, mass minus second_mass */
    double stiffness;           /* N/m, coupling */
    double damping;             /* N.s/m, coupling */
} ModelState;

#endif
