/* The operations that both FMI API files hand over to (slave.h): the state machine, the checks
 * of every argument, variable access through the variable table (generated into
 * model_variable_table.h), the model hooks and logging. The API files only translate their
 * version's types and calls; every message and every rule lives here once.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "model_variable_table.h"
#include "slave.h"

#define GET_STATES (SLAVE_IN(SLAVE_INITIALIZATION_MODE) | SLAVE_IN(SLAVE_STEP_MODE) | \
                    SLAVE_IN(SLAVE_EVENT_MODE) | SLAVE_IN(SLAVE_TERMINATED) | \
                    SLAVE_IN(SLAVE_ERROR_STATE))
#define SET_STATES (SLAVE_IN(SLAVE_INSTANTIATED) | SLAVE_IN(SLAVE_INITIALIZATION_MODE) | \
                    SLAVE_IN(SLAVE_STEP_MODE) | SLAVE_IN(SLAVE_EVENT_MODE))

/* Relative tolerance on the communication point against the model time, as in the FMI
 * reference models: masters compute communication points as k * h or by summation. */
#define TIME_TOLERANCE 1e-9

/* ---------------------------------------------------------------- logging */

static void log_message(const ModelInstance *inst, SlaveStatus status, int category,
                        const char *format, va_list args) {
    char message[512];
    if (!(inst->log_categories & (1u << category))) return;
    vsnprintf(message, sizeof(message), format, args);
    inst->interface->log(inst, status, kLogCategories[category], message);
}

void slave_log_error(const ModelInstance *inst, const char *format, ...) {
    va_list args;
    va_start(args, format);
    log_message(inst, SLAVE_ERROR, LOG_STATUS_ERROR, format, args);
    va_end(args);
}

void slave_log_event(const ModelInstance *inst, const char *format, ...) {
    va_list args;
    va_start(args, format);
    log_message(inst, SLAVE_OK, LOG_EVENTS, format, args);
    va_end(args);
}

SlaveStatus slave_fail(ModelInstance *inst, const char *format, ...) {
    va_list args;
    va_start(args, format);
    log_message(inst, SLAVE_ERROR, LOG_STATUS_ERROR, format, args);
    va_end(args);
    inst->state = SLAVE_ERROR_STATE;
    return SLAVE_ERROR;
}

/* ---------------------------------------------------------------- states */

static const char *state_name(const ModelInstance *inst) {
    return inst->interface->state_names[inst->state];
}

int slave_allowed(ModelInstance *inst, const char *function, unsigned states) {
    if (inst == NULL) return 0;
    if (states & SLAVE_IN(inst->state)) return 1;
    slave_log_error(inst, "%s: not allowed in state %s", function, state_name(inst));
    return 0;
}

static void set_start_values(ModelInstance *inst) {
    char *base = (char *)&inst->v;
    size_t i;
    for (i = 0; i < VARIABLE_COUNT; i++) {
        const VariableInfo *info = &kVariables[i];
        if (info->type == VARIABLE_REAL) {
            *(double *)(base + info->offset) = info->start;
        } else {
            *(int *)(base + info->offset) = (int)info->start;
        }
    }
    inst->outputs_stale = 1;
}

/* Whether a variable of this causality may be set in the instance's state. */
static int settable(const ModelInstance *inst, Causality causality) {
    if (causality == CAUSALITY_OUTPUT) return 0;
    if (causality == CAUSALITY_PARAMETER) {
        return inst->state == SLAVE_INSTANTIATED || inst->state == SLAVE_INITIALIZATION_MODE;
    }
    return 1;
}

/* Recomputes the outputs when an input or parameter changed. In initialization mode the initial
 * state is derived again first, so that parameters set there show in the outputs at once. */
static SlaveStatus refresh_outputs(ModelInstance *inst) {
    if (!inst->outputs_stale) return SLAVE_OK;
    if (inst->state == SLAVE_INITIALIZATION_MODE && model_initialize(inst) != SLAVE_OK) {
        return SLAVE_ERROR;
    }
    model_update_outputs(inst, inst->time);
    inst->outputs_stale = 0;
    return SLAVE_OK;
}

/* ---------------------------------------------------------------- logging categories */

/* Index of a log category by name, -1 when the model declares no such category. */
static int log_category_index(const char *name) {
    int i;
    for (i = 0; i < LOG_CATEGORY_COUNT; i++) {
        if (strcmp(name, kLogCategories[i]) == 0) return i;
    }
    return -1;
}

/* Errors stay logged whatever is chosen here; an unknown name leaves the choice as it was. */
SlaveStatus slave_set_debug_logging(ModelInstance *inst, const char *function, int logging_on,
                                    size_t count, const char *const categories[]) {
    unsigned mask = 0;
    size_t i;
    if (!slave_allowed(inst, function, SLAVE_ANY_STATE)) return SLAVE_ERROR;
    if (count > 0 && categories == NULL) {
        slave_log_error(inst, "%s: categories is NULL", function);
        return SLAVE_ERROR;
    }
    for (i = 0; i < count; i++) {
        int index = categories[i] ? log_category_index(categories[i]) : -1;
        if (index < 0) {
            slave_log_error(inst, "%s: unknown log category \"%s\" (expected one of the "
                            "LogCategories of modelDescription.xml)", function,
                            categories[i] ? categories[i] : "(null)");
            return SLAVE_ERROR;
        }
        mask |= 1u << index;
    }
    if (count == 0) mask = (1u << LOG_CATEGORY_COUNT) - 1u;
    inst->log_categories = logging_on ? inst->log_categories | mask : inst->log_categories & ~mask;
    inst->log_categories |= 1u << LOG_STATUS_ERROR;
    return SLAVE_OK;
}

/* ---------------------------------------------------------------- life cycle */

ModelInstance *slave_instantiate(const SlaveInterface *interface, SlaveMemory memory,
                                 size_t size, const char *instance_name, int logging_on) {
    ModelInstance *inst = (ModelInstance *)memory.allocate(1, size);
    if (inst == NULL) return NULL;
    inst->instance_name = (char *)memory.allocate(strlen(instance_name) + 1, sizeof(char));
    if (inst->instance_name == NULL) {
        memory.release(inst);
        return NULL;
    }
    strcpy(inst->instance_name, instance_name);
    inst->interface = interface;
    inst->memory = memory;
    inst->log_categories = 1u << LOG_STATUS_ERROR;
    if (logging_on) inst->log_categories = (1u << LOG_CATEGORY_COUNT) - 1u;
    inst->state = SLAVE_INSTANTIATED;
    set_start_values(inst);
    return inst;
}

void slave_free(ModelInstance *inst) {
    SlaveMemory memory;
    if (inst == NULL) return;
    memory = inst->memory;
    memory.release(inst->instance_name);
    memory.release(inst);
}

SlaveStatus slave_setup_experiment(ModelInstance *inst, const char *function, double start_time,
                                   int stop_time_defined, double stop_time) {
    if (!slave_allowed(inst, function, SLAVE_IN(SLAVE_INSTANTIATED))) return SLAVE_ERROR;
    if (!isfinite(start_time) || (stop_time_defined && !(stop_time >= start_time))) {
        return slave_fail(inst, "%s: startTime %g and stopTime %g are invalid", function,
                          start_time, stop_time);
    }
    inst->start_time = start_time;
    return SLAVE_OK;
}

SlaveStatus slave_enter_initialization_mode(ModelInstance *inst, const char *function) {
    if (!slave_allowed(inst, function, SLAVE_IN(SLAVE_INSTANTIATED))) return SLAVE_ERROR;
    inst->state = SLAVE_INITIALIZATION_MODE;
    inst->time = inst->start_time;
    if (model_initialize(inst) != SLAVE_OK) {
        inst->state = SLAVE_ERROR_STATE;
        return SLAVE_ERROR;
    }
    inst->outputs_stale = 1;
    return SLAVE_OK;
}

SlaveStatus slave_exit_initialization_mode(ModelInstance *inst, const char *function,
                                           SlaveState next) {
    if (!slave_allowed(inst, function, SLAVE_IN(SLAVE_INITIALIZATION_MODE))) return SLAVE_ERROR;
    /* Parameters may have been set in initialization mode: derive everything again. */
    if (model_initialize(inst) != SLAVE_OK) {
        inst->state = SLAVE_ERROR_STATE;
        return SLAVE_ERROR;
    }
    inst->outputs_stale = 1;
    inst->state = next;
    return SLAVE_OK;
}

SlaveStatus slave_terminate(ModelInstance *inst, const char *function) {
    unsigned states = SLAVE_IN(SLAVE_STEP_MODE) | SLAVE_IN(SLAVE_EVENT_MODE) |
                      SLAVE_IN(SLAVE_ERROR_STATE);
    if (!slave_allowed(inst, function, states)) return SLAVE_ERROR;
    inst->state = SLAVE_TERMINATED;
    return SLAVE_OK;
}

SlaveStatus slave_reset(ModelInstance *inst, const char *function) {
    if (!slave_allowed(inst, function, SLAVE_ANY_STATE)) return SLAVE_ERROR;
    memset(&inst->s, 0, sizeof(inst->s));
    inst->start_time = 0.0;
    inst->time = 0.0;
    set_start_values(inst);
    inst->state = SLAVE_INSTANTIATED;
    return SLAVE_OK;
}

/* ---------------------------------------------------------------- variable access */

/* Checks the call and its arrays before a getter or setter; 0 after logging when it fails. */
static int access_allowed(ModelInstance *inst, const char *function, unsigned states,
                          const SlaveValueReference vr[], size_t count, const void *values,
                          size_t value_count) {
    if (!slave_allowed(inst, function, states)) return 0;
    if (count > 0 && (vr == NULL || values == NULL)) {
        slave_fail(inst, "%s: vr or value is NULL", function);
        return 0;
    }
    if (value_count != count) {
        slave_fail(inst, "%s: %zu values for %zu value references (expected one value per "
                   "reference: every variable is a scalar)", function, value_count, count);
        return 0;
    }
    return 1;
}

/* 1 when vr is the independent variable time, which the version declares. */
static int is_time(const ModelInstance *inst, SlaveValueReference vr) {
    return inst->interface->declares_time && vr == TIME_VALUE_REFERENCE;
}

/* The row of variable vr if it is of `type`; else NULL, logged and failed. */
static const VariableInfo *variable_of_type(ModelInstance *inst, const char *function,
                                            SlaveValueReference vr, VariableType type) {
    if (vr < VARIABLE_COUNT && kVariables[vr].type == type) return &kVariables[vr];
    slave_fail(inst, "%s: no %s variable has value reference %u", function,
               type == VARIABLE_REAL ? inst->interface->real_type : inst->interface->integer_type,
               vr);
    return NULL;
}

/* Reals also read the time. The outputs are Reals: reading them first recomputes them when an
 * input or parameter changed. */
SlaveStatus slave_get_values(ModelInstance *inst, const char *function, VariableType type,
                              const SlaveValueReference vr[], size_t count, void *values,
                              size_t value_count) {
    const char *base = (const char *)&inst->v;
    size_t i;
    if (!access_allowed(inst, function, GET_STATES, vr, count, values, value_count)) {
        return SLAVE_ERROR;
    }
    if (type == VARIABLE_REAL && refresh_outputs(inst) != SLAVE_OK) {
        inst->state = SLAVE_ERROR_STATE;
        return SLAVE_ERROR;
    }
    for (i = 0; i < count; i++) {
        const VariableInfo *info;
        if (type == VARIABLE_REAL && is_time(inst, vr[i])) {
            ((double *)values)[i] = inst->time;
            continue;
        }
        info = variable_of_type(inst, function, vr[i], type);
        if (info == NULL) return SLAVE_ERROR;
        if (type == VARIABLE_REAL) {
            ((double *)values)[i] = *(const double *)(base + info->offset);
        } else {
            ((int *)values)[i] = *(const int *)(base + info->offset);
        }
    }
    return SLAVE_OK;
}

/* 1 when values[i] suits the variable: within its limits, and for a Real finite (and > 0 when
 * it must be positive); else logs, fails and returns 0. */
static int valid_value(ModelInstance *inst, const char *function, const VariableInfo *info,
                       const void *values, size_t i) {
    if (info->type == VARIABLE_INTEGER) {
        int value = ((const int *)values)[i];
        if (value >= info->min && value <= info->max) return 1;
        slave_fail(inst, "%s: %s = %d is out of range [%d, %d]", function, info->name, value,
                   (int)info->min, (int)info->max);
        return 0;
    } else {
        double value = ((const double *)values)[i];
        if (isfinite(value) && value >= info->min && value <= info->max &&
            (!info->positive || value > 0.0)) {
            return 1;
        }
        slave_fail(inst, "%s: %s = %g is invalid (expected a finite value%s in [%g, %g])",
                   function, info->name, value, info->positive ? " > 0" : "", info->min,
                   info->max);
        return 0;
    }
}

/* Each value is checked before it is set. */
SlaveStatus slave_set_values(ModelInstance *inst, const char *function, VariableType type,
                              const SlaveValueReference vr[], size_t count, const void *values,
                              size_t value_count) {
    char *base = (char *)&inst->v;
    size_t i;
    if (!access_allowed(inst, function, SET_STATES, vr, count, values, value_count)) {
        return SLAVE_ERROR;
    }
    for (i = 0; i < count; i++) {
        const VariableInfo *info;
        if (type == VARIABLE_REAL && is_time(inst, vr[i])) {
            return slave_fail(inst, "%s: time cannot be set (the independent variable)",
                              function);
        }
        info = variable_of_type(inst, function, vr[i], type);
        if (info == NULL) return SLAVE_ERROR;
        if (!settable(inst, info->causality)) {
            return slave_fail(inst, "%s: %s cannot be set in state %s", function, info->name,
                              state_name(inst));
        }
        if (!valid_value(inst, function, info, values, i)) return SLAVE_ERROR;
        if (type == VARIABLE_REAL) {
            *(double *)(base + info->offset) = ((const double *)values)[i];
        } else {
            *(int *)(base + info->offset) = ((const int *)values)[i];
        }
    }
    inst->outputs_stale = 1;
    return SLAVE_OK;
}

SlaveStatus slave_no_variables_of_type(ModelInstance *inst, const char *function, size_t count) {
    if (!slave_allowed(inst, function, SLAVE_ANY_STATE)) return SLAVE_ERROR;
    if (count == 0) return SLAVE_OK;
    return slave_fail(inst, "%s: the model has no variables of this type", function);
}

/* ---------------------------------------------------------------- stepping */

SlaveStatus slave_do_step(ModelInstance *inst, const char *function, double t, double h) {
    if (!slave_allowed(inst, function, SLAVE_IN(SLAVE_STEP_MODE))) return SLAVE_ERROR;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0)) {
        return slave_fail(inst, "%s: step from t = %g with h = %g is invalid (expected finite "
                          "values and h > 0)", function, t, h);
    }
    if (fabs(t - inst->time) > TIME_TOLERANCE * fmax(1.0, fabs(inst->time))) {
        return slave_fail(inst, "%s: currentCommunicationPoint = %.17g s is not the model time "
                          "%.17g s (expected equal within a relative %g)", function, t,
                          inst->time, TIME_TOLERANCE);
    }
    if (model_do_step(inst, t, h) != SLAVE_OK) {
        inst->state = SLAVE_ERROR_STATE;
        return SLAVE_ERROR;
    }
    inst->time = t + h;
    inst->outputs_stale = 1;
    return SLAVE_OK;
}

SlaveStatus slave_unsupported(ModelInstance *inst, const char *function) {
    if (!slave_allowed(inst, function, SLAVE_ANY_STATE)) return SLAVE_ERROR;
    slave_log_error(inst, "%s: not supported by this model", function);
    return SLAVE_ERROR;
}
