/* FMI 2.0 co-simulation API shared by every model of this project.
 *
 * Thin API functions: each one checks the instance, the state machine and its arguments, then
 * hands over to the variable table (generated into model_variables.h) or to a model hook
 * (model_initialize, model_do_step, model_update_outputs). Every failure returns fmi2Error with
 * a message through the importer's logger; nothing here aborts the process.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "model_variable_table.h"
#include "slave.h"

#define ALL_STATES (SLAVE_INSTANTIATED | SLAVE_INITIALIZATION_MODE | SLAVE_STEP_COMPLETE | \
                    SLAVE_TERMINATED | SLAVE_ERROR)
#define MASK_GET (SLAVE_INITIALIZATION_MODE | SLAVE_STEP_COMPLETE | SLAVE_TERMINATED | SLAVE_ERROR)
#define MASK_SET (SLAVE_INSTANTIATED | SLAVE_INITIALIZATION_MODE | SLAVE_STEP_COMPLETE)

static const size_t kRealCount = REAL_VARIABLE_COUNT;
static const size_t kIntegerCount = INTEGER_VARIABLE_COUNT;

static void log_message(const ModelInstance *inst, fmi2Status status, int category,
                        const char *format, va_list args) {
    char message[512];
    if (inst->functions.logger == NULL || !(inst->log_categories & (1u << category))) return;
    vsnprintf(message, sizeof(message), format, args);
    inst->functions.logger(inst->functions.componentEnvironment, inst->instance_name, status,
                           kLogCategories[category], "%s", message);
}

void slave_log_error(const ModelInstance *inst, const char *format, ...) {
    va_list args;
    va_start(args, format);
    log_message(inst, fmi2Error, LOG_STATUS_ERROR, format, args);
    va_end(args);
}

void slave_log_event(const ModelInstance *inst, const char *format, ...) {
    va_list args;
    va_start(args, format);
    log_message(inst, fmi2OK, LOG_EVENTS, format, args);
    va_end(args);
}

static const char *state_name(SlaveState state) {
    switch (state) {
        case SLAVE_INSTANTIATED: return "Instantiated";
        case SLAVE_INITIALIZATION_MODE: return "InitializationMode";
        case SLAVE_STEP_COMPLETE: return "StepComplete";
        case SLAVE_TERMINATED: return "Terminated";
        default: return "Error";
    }
}

/* Returns 1 when the call is allowed in the instance's state; logs and returns 0 otherwise. */
static int allowed(ModelInstance *inst, const char *function, int mask) {
    if (inst == NULL) return 0;
    if (inst->state & mask) return 1;
    slave_log_error(inst, "%s: not allowed in state %s", function, state_name(inst->state));
    return 0;
}

static fmi2Status fail(ModelInstance *inst) {
    inst->state = SLAVE_ERROR;
    return fmi2Error;
}

static void set_start_values(ModelInstance *inst) {
    char *base = (char *)&inst->v;
    size_t i;
    for (i = 0; i < kRealCount; i++) {
        *(double *)(base + kRealVariables[i].offset) = kRealVariables[i].start;
    }
    for (i = 0; i < kIntegerCount; i++) {
        *(int *)(base + kIntegerVariables[i].offset) = kIntegerVariables[i].start;
    }
    inst->outputs_stale = 1;
}

/* Whether a variable of this causality may be set in the instance's state. */
static int settable(const ModelInstance *inst, Causality causality) {
    if (causality == CAUSALITY_OUTPUT) return 0;
    if (causality == CAUSALITY_PARAMETER) {
        return (inst->state & (SLAVE_INSTANTIATED | SLAVE_INITIALIZATION_MODE)) != 0;
    }
    return 1;
}

/* Recomputes the outputs when an input or parameter changed. In initialization mode the initial
 * state is derived again first, so that parameters set there show in the outputs at once. */
static fmi2Status refresh_outputs(ModelInstance *inst) {
    if (!inst->outputs_stale) return fmi2OK;
    if (inst->state == SLAVE_INITIALIZATION_MODE && model_initialize(inst) != fmi2OK) {
        return fmi2Error;
    }
    model_update_outputs(inst, inst->time);
    inst->outputs_stale = 0;
    return fmi2OK;
}

/* ---------------------------------------------------------------- inquiry and logging */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

/* Index of a log category by name, -1 when the model declares no such category. */
static int log_category_index(const char *name) {
    int i;
    for (i = 0; i < LOG_CATEGORY_COUNT; i++) {
        if (strcmp(name, kLogCategories[i]) == 0) return i;
    }
    return -1;
}

/* Enables or disables the named categories (all of them when nCategories is 0). Errors stay
 * logged whatever is chosen here. */
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    ModelInstance *inst = (ModelInstance *)c;
    unsigned mask = 0;
    size_t i;
    if (!allowed(inst, "fmi2SetDebugLogging", ALL_STATES)) return fmi2Error;
    if (nCategories > 0 && categories == NULL) {
        slave_log_error(inst, "fmi2SetDebugLogging: categories is NULL");
        return fmi2Error;
    }
    for (i = 0; i < nCategories; i++) {
        int index = categories[i] ? log_category_index(categories[i]) : -1;
        if (index < 0) {
            slave_log_error(inst, "fmi2SetDebugLogging: unknown log category \"%s\" (expected "
                            "one of the LogCategories of modelDescription.xml)",
                            categories[i] ? categories[i] : "(null)");
            return fmi2Error;
        }
        mask |= 1u << index;
    }
    if (nCategories == 0) mask = (1u << LOG_CATEGORY_COUNT) - 1u;
    inst->log_categories = loggingOn ? inst->log_categories | mask : inst->log_categories & ~mask;
    inst->log_categories |= 1u << LOG_STATUS_ERROR;
    return fmi2OK;
}

/* ---------------------------------------------------------------- life cycle */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    ModelInstance *inst;
    const char *name = instanceName ? instanceName : "";
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL || functions->freeMemory == NULL) {
        return NULL;
    }
    if (fmuType != fmi2CoSimulation || fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        if (functions->logger) {
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                              "fmi2Instantiate: %s", fmuType != fmi2CoSimulation
                                  ? "only co-simulation is supported"
                                  : "GUID does not match this binary");
        }
        return NULL;
    }
    inst = (ModelInstance *)functions->allocateMemory(1, sizeof(ModelInstance));
    if (inst == NULL) return NULL;
    inst->instance_name = (char *)functions->allocateMemory(strlen(name) + 1, sizeof(char));
    if (inst->instance_name == NULL) {
        functions->freeMemory(inst);
        return NULL;
    }
    strcpy(inst->instance_name, name);
    inst->functions = *functions;
    inst->log_categories = 1u << LOG_STATUS_ERROR;
    if (loggingOn) inst->log_categories = (1u << LOG_CATEGORY_COUNT) - 1u;
    inst->state = SLAVE_INSTANTIATED;
    set_start_values(inst);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    ModelInstance *inst = (ModelInstance *)c;
    fmi2CallbackFreeMemory free_memory;
    if (inst == NULL) return;
    free_memory = inst->functions.freeMemory;
    free_memory(inst->instance_name);
    free_memory(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    ModelInstance *inst = (ModelInstance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    if (!allowed(inst, "fmi2SetupExperiment", SLAVE_INSTANTIATED)) return fmi2Error;
    if (!isfinite(startTime) || (stopTimeDefined && !(stopTime >= startTime))) {
        slave_log_error(inst, "fmi2SetupExperiment: startTime %g and stopTime %g are invalid",
                        startTime, stopTime);
        return fail(inst);
    }
    inst->start_time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ModelInstance *inst = (ModelInstance *)c;
    if (!allowed(inst, "fmi2EnterInitializationMode", SLAVE_INSTANTIATED)) return fmi2Error;
    inst->state = SLAVE_INITIALIZATION_MODE;
    inst->time = inst->start_time;
    if (model_initialize(inst) != fmi2OK) return fail(inst);
    inst->outputs_stale = 1;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ModelInstance *inst = (ModelInstance *)c;
    if (!allowed(inst, "fmi2ExitInitializationMode", SLAVE_INITIALIZATION_MODE)) return fmi2Error;
    /* Parameters may have been set in initialization mode: derive everything again. */
    if (model_initialize(inst) != fmi2OK) return fail(inst);
    inst->outputs_stale = 1;
    inst->state = SLAVE_STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    ModelInstance *inst = (ModelInstance *)c;
    if (!allowed(inst, "fmi2Terminate", SLAVE_STEP_COMPLETE | SLAVE_ERROR)) return fmi2Error;
    inst->state = SLAVE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    ModelInstance *inst = (ModelInstance *)c;
    if (!allowed(inst, "fmi2Reset", ALL_STATES)) return fmi2Error;
    memset(&inst->s, 0, sizeof(inst->s));
    inst->start_time = 0.0;
    inst->time = 0.0;
    set_start_values(inst);
    inst->state = SLAVE_INSTANTIATED;
    return fmi2OK;
}

/* ---------------------------------------------------------------- variable access */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    ModelInstance *inst = (ModelInstance *)c;
    const char *base;
    size_t i;
    if (!allowed(inst, "fmi2GetReal", MASK_GET)) return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        slave_log_error(inst, "fmi2GetReal: vr or value is NULL");
        return fail(inst);
    }
    if (refresh_outputs(inst) != fmi2OK) return fail(inst);
    base = (const char *)&inst->v;
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= kRealCount) {
            slave_log_error(inst, "fmi2GetReal: no Real variable has value reference %u", vr[i]);
            return fail(inst);
        }
        value[i] = *(const double *)(base + kRealVariables[vr[i]].offset);
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    ModelInstance *inst = (ModelInstance *)c;
    char *base;
    size_t i;
    if (!allowed(inst, "fmi2SetReal", MASK_SET)) return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        slave_log_error(inst, "fmi2SetReal: vr or value is NULL");
        return fail(inst);
    }
    base = (char *)&inst->v;
    for (i = 0; i < nvr; i++) {
        const RealVariableInfo *info;
        if (vr[i] >= kRealCount) {
            slave_log_error(inst, "fmi2SetReal: no Real variable has value reference %u", vr[i]);
            return fail(inst);
        }
        info = &kRealVariables[vr[i]];
        if (!settable(inst, info->causality)) {
            slave_log_error(inst, "fmi2SetReal: %s cannot be set in state %s", info->name,
                            state_name(inst->state));
            return fail(inst);
        }
        if (!isfinite(value[i]) || value[i] < info->min || value[i] > info->max ||
            (info->positive && !(value[i] > 0.0))) {
            slave_log_error(inst, "fmi2SetReal: %s = %g is invalid (expected a finite value%s "
                            "in [%g, %g])", info->name, value[i],
                            info->positive ? " > 0" : "", info->min, info->max);
            return fail(inst);
        }
        *(double *)(base + info->offset) = value[i];
    }
    inst->outputs_stale = 1;
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    ModelInstance *inst = (ModelInstance *)c;
    const char *base;
    size_t i;
    if (!allowed(inst, "fmi2GetInteger", MASK_GET)) return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        slave_log_error(inst, "fmi2GetInteger: vr or value is NULL");
        return fail(inst);
    }
    base = (const char *)&inst->v;
    for (i = 0; i < nvr; i++) {
        size_t index = vr[i] - kRealCount;
        if (vr[i] < kRealCount || index >= kIntegerCount) {
            slave_log_error(inst, "fmi2GetInteger: no Integer variable has value reference %u",
                            vr[i]);
            return fail(inst);
        }
        value[i] = *(const int *)(base + kIntegerVariables[index].offset);
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    ModelInstance *inst = (ModelInstance *)c;
    char *base;
    size_t i;
    if (!allowed(inst, "fmi2SetInteger", MASK_SET)) return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        slave_log_error(inst, "fmi2SetInteger: vr or value is NULL");
        return fail(inst);
    }
    base = (char *)&inst->v;
    for (i = 0; i < nvr; i++) {
        const IntegerVariableInfo *info;
        size_t index = vr[i] - kRealCount;
        if (vr[i] < kRealCount || index >= kIntegerCount) {
            slave_log_error(inst, "fmi2SetInteger: no Integer variable has value reference %u",
                            vr[i]);
            return fail(inst);
        }
        info = &kIntegerVariables[index];
        if (!settable(inst, info->causality)) {
            slave_log_error(inst, "fmi2SetInteger: %s cannot be set in state %s", info->name,
                            state_name(inst->state));
            return fail(inst);
        }
        if (value[i] < info->min || value[i] > info->max) {
            slave_log_error(inst, "fmi2SetInteger: %s = %d is out of range [%d, %d]", info->name,
                            value[i], info->min, info->max);
            return fail(inst);
        }
        *(int *)(base + info->offset) = value[i];
    }
    inst->outputs_stale = 1;
    return fmi2OK;
}

static fmi2Status no_variables_of_type(fmi2Component c, const char *function, size_t nvr) {
    ModelInstance *inst = (ModelInstance *)c;
    if (!allowed(inst, function, ALL_STATES)) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    slave_log_error(inst, "%s: the model has no variables of this type", function);
    return fail(inst);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return no_variables_of_type(c, "fmi2GetBoolean", nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return no_variables_of_type(c, "fmi2SetBoolean", nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)vr;
    (void)value;
    return no_variables_of_type(c, "fmi2GetString", nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)vr;
    (void)value;
    return no_variables_of_type(c, "fmi2SetString", nvr);
}

/* ---------------------------------------------------------------- stepping */

/* Relative tolerance on currentCommunicationPoint against the model time, as in the FMI
 * reference models: masters compute communication points as k * h or by summation. */
#define TIME_TOLERANCE 1e-9

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    ModelInstance *inst = (ModelInstance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!allowed(inst, "fmi2DoStep", SLAVE_STEP_COMPLETE)) return fmi2Error;
    if (!isfinite(currentCommunicationPoint) || !isfinite(communicationStepSize) ||
        !(communicationStepSize > 0.0)) {
        slave_log_error(inst, "fmi2DoStep: step from t = %g with h = %g is invalid (expected "
                        "finite values and h > 0)", currentCommunicationPoint,
                        communicationStepSize);
        return fail(inst);
    }
    if (fabs(currentCommunicationPoint - inst->time) >
        TIME_TOLERANCE * fmax(1.0, fabs(inst->time))) {
        slave_log_error(inst, "fmi2DoStep: currentCommunicationPoint = %.17g s is not the model "
                        "time %.17g s (expected equal within a relative %g)",
                        currentCommunicationPoint, inst->time, TIME_TOLERANCE);
        return fail(inst);
    }
    if (model_do_step(inst, currentCommunicationPoint, communicationStepSize) != fmi2OK) {
        return fail(inst);
    }
    inst->time = currentCommunicationPoint + communicationStepSize;
    inst->outputs_stale = 1;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    ModelInstance *inst = (ModelInstance *)c;
    if (!allowed(inst, "fmi2CancelStep", ALL_STATES)) return fmi2Error;
    slave_log_error(inst, "fmi2CancelStep: doStep always completes synchronously");
    return fmi2Error;
}

static fmi2Status unsupported(fmi2Component c, const char *function) {
    ModelInstance *inst = (ModelInstance *)c;
    if (!allowed(inst, function, ALL_STATES)) return fmi2Error;
    slave_log_error(inst, "%s: not supported by this model", function);
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetRealStatus");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetBooleanStatus");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2FreeFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate;
    (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    (void)FMUstate;
    (void)serializedState;
    (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    (void)serializedState;
    (void)size;
    (void)FMUstate;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}
