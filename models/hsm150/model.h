/* hsm150: state of the rigid rotor of the HSM150 bench. Variables live in the generated table. */
#ifndef MODEL_H
#define MODEL_H

#include "command_delay.h"
#include "model_variables.h"

typedef struct {
    /* states */
    double angle;               /* rad, true rotor angle */
    double speed;               /* rad/s, true rotor speed */
    int stuck;                  /* 1 while static friction holds the rotor */
    int direction;              /* sign of the sliding speed seen by Coulomb friction */

    /* discrete states of the drive and the encoder */
    CommandDelay command;       /* A, current commands waiting out the dead time */
    double encoder;             /* rad, encoder angle at the last communication point */
    double encoder_speed;       /* rad/s, its difference over the last step, per the step */
} ModelState;

#endif
