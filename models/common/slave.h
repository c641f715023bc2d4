/* The FMI 2.0 co-simulation slave shared by every model: instance data and the model hooks. */
#ifndef SLAVE_H
#define SLAVE_H

#include "fmi2Functions.h"
#include "model.h"

/* Functions shared between the slave and the model's translation unit are hidden from the
 * dynamic symbol table whatever the compiler flags, so that two models loaded in one process
 * never bind to each other's functions: the binary exports the fmi2 functions only. */
#if defined(__GNUC__) && !defined(_WIN32) && !defined(__CYGWIN__)
#define SLAVE_INTERNAL __attribute__((visibility("hidden")))
#else
#define SLAVE_INTERNAL
#endif

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
    unsigned log_categories;    /* bit i set: LogCategories entry i is passed to the logger */
    SlaveState state;
    double start_time;          /* s */
    double time;                /* s, model time of the current state */
    int outputs_stale;          /* 1 when outputs must be recomputed before a fmi2GetReal */
    ModelVariables v;           /* every variable of the variable table */
    ModelState s;               /* continuous and discrete states, derived constants */
} ModelInstance;

/* Logs an error (category logStatusError) through the importer's logger. Errors are always
 * logged, whatever fmi2SetDebugLogging chose. */
SLAVE_INTERNAL void slave_log_error(const ModelInstance *inst, const char *format, ...);

/* Logs a model event (category logEvents: stick/slip transitions, step limits, split steps)
 * when the importer enabled that category. */
SLAVE_INTERNAL void slave_log_event(const ModelInstance *inst, const char *format, ...);

/* Model hooks, implemented once per model (models/<name>/model.c). */

/* Checks the parameters together, derives constants and sets the initial state at the instance's
 * start time. Called on entering initialization mode, on reading outputs in initialization mode
 * after a parameter changed, and on leaving initialization mode. */
SLAVE_INTERNAL fmi2Status model_initialize(ModelInstance *inst);

/* Advances the model from t (s) by h (s). */
SLAVE_INTERNAL fmi2Status model_do_step(ModelInstance *inst, double t, double h);

/* Computes the outputs from the state at time t (s). */
SLAVE_INTERNAL void model_update_outputs(ModelInstance *inst, double t);

#endif
