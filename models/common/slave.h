/* The FMI 2.0 co-simulation slave shared by every model: instance data and the model hooks. */
#ifndef SLAVE_H
#define SLAVE_H

#include "fmi2Functions.h"
#include "model.h"

typedef enum {
    SLAVE_INSTANTIATED = 1 << 0,
    SLAVE_INITIALIZATION_MODE = 1 << 1,
    SLAVE_STEP_COMPLETE = 1 << 2,
    SLAVE_TERMINATED = 1 << 3,
    SLAVE_ERROR = 1 << 4
} SlaveState;

typedef struct ModelInstance {
    char *instance_name;
    fmi2CallbackFunctions functions;
    fmi2Boolean logging_on;
    SlaveState state;
    double start_time;          /* s */
    double time;                /* s, model time of the current state */
    int outputs_stale;          /* 1 when outputs must be recomputed before a fmi2GetReal */
    ModelVariables v;           /* every variable of the variable table */
    ModelState s;               /* continuous and discrete states, derived constants */
} ModelInstance;

/* Logs an error through the importer's logger, whether or not debug logging is on. */
void slave_log_error(const ModelInstance *inst, const char *format, ...);

/* Model hooks, implemented once per model (models/<name>/model.c). */

/* Checks the parameters together, derives constants and sets the initial state. */
fmi2Status model_initialize(ModelInstance *inst);

/* Advances the model from t (s) by h (s). */
fmi2Status model_do_step(ModelInstance *inst, double t, double h);

/* Computes the outputs from the state at time t (s). */
void model_update_outputs(ModelInstance *inst, double t);

#endif
