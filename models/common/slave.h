/* The co-simulation slave shared by every model and both FMI versions: instance data, the
 * model hooks, and the operations that the FMI 2.0 and FMI 3.0 API files (fmi2_slave.c,
 * fmi3_slave.c) hand over to. Nothing here names an FMI type: statuses are SlaveStatus, whose
 * values are those of fmi2Status and fmi3Status alike. */
#ifndef SLAVE_H
#define SLAVE_H

#include <stddef.h>

#include "model.h"
#include "variable_info.h"

/* Functions shared between the translation units of one binary are hidden from the dynamic
 * symbol table whatever the compiler flags, so that two models loaded in one process never bind
 * to each other's functions: the binary exports the functions of its FMI version only. */
#if defined(__GNUC__) && !defined(_WIN32) && !defined(__CYGWIN__)
#define SLAVE_INTERNAL __attribute__((visibility("hidden")))
#else
#define SLAVE_INTERNAL
#endif

/* The statuses the slave returns; the values of fmi2OK / fmi2Error and fmi3OK / fmi3Error. */
typedef enum {
    SLAVE_OK = 0,
    SLAVE_ERROR = 3
} SlaveStatus;

/* States of an instance. FMI 2.0 calls SLAVE_STEP_MODE "StepComplete" and has no event mode. */
typedef enum {
    SLAVE_INSTANTIATED,
    SLAVE_INITIALIZATION_MODE,
    SLAVE_STEP_MODE,
    SLAVE_EVENT_MODE,
    SLAVE_TERMINATED,
    SLAVE_ERROR_STATE,
    SLAVE_STATE_COUNT
} SlaveState;

/* A set of states, for the calls allowed in them. */
#define SLAVE_IN(state) (1u << (state))
#define SLAVE_ANY_STATE ((1u << SLAVE_STATE_COUNT) - 1u)

/* Value references: fmi2ValueReference and fmi3ValueReference are both this type here. */
typedef unsigned int SlaveValueReference;

struct ModelInstance;

/* What differs between the FMI versions, in one constant table per version. */
typedef struct {
    /* Passes a formatted message to the importer's logger, when it gave one. */
    void (*log)(const struct ModelInstance *inst, SlaveStatus status, const char *category,
                const char *message);
    const char *state_names[SLAVE_STATE_COUNT];   /* as the version's standard names them */
    const char *real_type;                         /* "Real" or "Float64" */
    const char *integer_type;                      /* "Integer" or "Int32" */
    int declares_time;   /* 1: TIME_VALUE_REFERENCE is the independent variable (FMI 3.0) */
} SlaveInterface;

/* Memory for an instance: the importer's functions (FMI 2.0) or the C library's (FMI 3.0). */
typedef struct {
    void *(*allocate)(size_t count, size_t size);   /* zeroed, as calloc */
    void (*release)(void *memory);
} SlaveMemory;

typedef struct ModelInstance {
    const SlaveInterface *interface;
    SlaveMemory memory;
    char *instance_name;
    unsigned log_categories;    /* bit i set: LogCategories entry i is passed to the logger */
    SlaveState state;
    double start_time;          /* s */
    double time;                /* s, model time of the current state */
    int outputs_stale;          /* 1 when outputs must be recomputed before they are read */
    ModelVariables v;           /* every variable of the variable table */
    ModelState s;               /* continuous and discrete states, derived constants */
} ModelInstance;

/* ---------------------------------------------------------------- for the models */

/* Logs an error (category logStatusError) through the importer's logger. Errors are always
 * logged, whatever the importer chose with SetDebugLogging. */
SLAVE_INTERNAL void slave_log_error(const ModelInstance *inst, const char *format, ...);

/* Logs a model event (category logEvents: stick/slip transitions, step limits, split steps)
 * when the importer enabled that category. */
SLAVE_INTERNAL void slave_log_event(const ModelInstance *inst, const char *format, ...);

/* Model hooks, implemented once per model (models/<name>/model.c). */

/* Checks the parameters together, derives constants and sets the initial state at the instance's
 * start time. Called on entering initialization mode, on reading outputs in initialization mode
 * after a parameter changed, and on leaving initialization mode. */
SLAVE_INTERNAL SlaveStatus model_initialize(ModelInstance *inst);

/* Advances the model from t (s) by h (s). */
SLAVE_INTERNAL SlaveStatus model_do_step(ModelInstance *inst, double t, double h);

/* Computes the outputs from the state at time t (s). */
SLAVE_INTERNAL void model_update_outputs(ModelInstance *inst, double t);

/* ---------------------------------------------------------------- for the FMI API files
 *
 * Each operation checks the instance, the state it is called in and its arguments; `function`
 * (the API function's name) begins every message it logs. A failing operation returns
 * SLAVE_ERROR after logging why; one that failed on the instance's values or state also puts
 * the instance in SLAVE_ERROR_STATE, from which only reset, terminate, free and the getters
 * are allowed. */

/* A new instance of `size` bytes (at least sizeof(ModelInstance): an API file may keep its own
 * data behind the ModelInstance, its first member) at its start values, with errors logged and,
 * when logging_on, every other category too; NULL when memory runs out. */
SLAVE_INTERNAL ModelInstance *slave_instantiate(const SlaveInterface *interface,
                                                SlaveMemory memory, size_t size,
                                                const char *instance_name, int logging_on);

SLAVE_INTERNAL void slave_free(ModelInstance *inst);

/* 1 when `function` may be called in the instance's state (one of `states`, a SLAVE_IN set);
 * logs and returns 0 otherwise, and for a NULL instance. */
SLAVE_INTERNAL int slave_allowed(ModelInstance *inst, const char *function, unsigned states);

/* Logs an error (printf-style) and puts the instance in SLAVE_ERROR_STATE; SLAVE_ERROR. */
SLAVE_INTERNAL SlaveStatus slave_fail(ModelInstance *inst, const char *format, ...);

/* Switches the named log categories on or off (all of them when count is 0). */
SLAVE_INTERNAL SlaveStatus slave_set_debug_logging(ModelInstance *inst, const char *function,
                                                   int logging_on, size_t count,
                                                   const char *const categories[]);

/* The experiment's start time (s) and, when defined, its stop time (s). */
SLAVE_INTERNAL SlaveStatus slave_setup_experiment(ModelInstance *inst, const char *function,
                                                  double start_time, int stop_time_defined,
                                                  double stop_time);

SLAVE_INTERNAL SlaveStatus slave_enter_initialization_mode(ModelInstance *inst,
                                                           const char *function);

/* Derives everything from the parameters once more and moves on to `next` (step or event
 * mode). */
SLAVE_INTERNAL SlaveStatus slave_exit_initialization_mode(ModelInstance *inst,
                                                          const char *function, SlaveState next);

SLAVE_INTERNAL SlaveStatus slave_terminate(ModelInstance *inst, const char *function);

/* Back to the instantiated state with the start values. */
SLAVE_INTERNAL SlaveStatus slave_reset(ModelInstance *inst, const char *function);

/* Variable access through the variable table, by value reference: values[] holds doubles for
 * VARIABLE_REAL and ints for VARIABLE_INTEGER, value_count of them (FMI 3.0's nValues; FMI 2.0
 * passes count): every variable is a scalar, so value_count must equal count. */
SLAVE_INTERNAL SlaveStatus slave_get_values(ModelInstance *inst, const char *function,
                                            VariableType type, const SlaveValueReference vr[],
                                            size_t count, void *values, size_t value_count);
SLAVE_INTERNAL SlaveStatus slave_set_values(ModelInstance *inst, const char *function,
                                            VariableType type, const SlaveValueReference vr[],
                                            size_t count, const void *values,
                                            size_t value_count);

/* For the getters and setters of a type the model has none of: OK for no variables. */
SLAVE_INTERNAL SlaveStatus slave_no_variables_of_type(ModelInstance *inst, const char *function,
                                                      size_t count);

/* One communication step from t (s), which must be the model time, by h (s). */
SLAVE_INTERNAL SlaveStatus slave_do_step(ModelInstance *inst, const char *function, double t,
                                         double h);

/* For a function of the standard that this model does not offer. */
SLAVE_INTERNAL SlaveStatus slave_unsupported(ModelInstance *inst, const char *function);

#endif
