/* FMI 2.0 co-simulation API shared by every model of this project.
 *
 * Thin API functions: each one translates its arguments and hands over to the slave shared with
 * the FMI 3.0 API (slave.c), which checks the instance, the state machine and the arguments,
 * then goes to the variable table or to a model hook. Every failure returns fmi2Error with a
 * message through the importer's logger; nothing here aborts the process.
 */
#include <string.h>

#include "fmi2Functions.h"
#include "slave.h"

/* The shared slave's statuses are this version's: its functions return them cast. */
typedef char slave_status_is_fmi2_status[
    (int)SLAVE_OK == (int)fmi2OK && (int)SLAVE_ERROR == (int)fmi2Error ? 1 : -1];

/* An instance: the shared slave's data, then the importer's callbacks. */
typedef struct {
    ModelInstance model;               /* first: what slave.c works on */
    fmi2CallbackFunctions functions;   /* the importer's logger and memory functions */
} Fmi2Instance;

static void log_to_importer(const ModelInstance *inst, SlaveStatus status, const char *category,
                            const char *message) {
    const fmi2CallbackFunctions *functions = &((const Fmi2Instance *)inst)->functions;
    if (functions->logger == NULL) return;
    functions->logger(functions->componentEnvironment, inst->instance_name, (fmi2Status)status,
                      category, "%s", message);
}

static const SlaveInterface kFmi2Interface = {
    .log = log_to_importer,
    .state_names = {
        [SLAVE_INSTANTIATED] = "Instantiated",
        [SLAVE_INITIALIZATION_MODE] = "InitializationMode",
        [SLAVE_STEP_MODE] = "StepComplete",
        [SLAVE_EVENT_MODE] = "EventMode",   /* never entered: FMI 2.0 co-simulation has none */
        [SLAVE_TERMINATED] = "Terminated",
        [SLAVE_ERROR_STATE] = "Error",
    },
    .real_type = "Real",
    .integer_type = "Integer",
    .declares_time = 0,
};

#define INSTANCE(c) ((ModelInstance *)(c))

/* ---------------------------------------------------------------- inquiry and logging */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

/* Enables or disables the named categories (all of them when nCategories is 0). Errors stay
 * logged whatever is chosen here. */
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    return (fmi2Status)slave_set_debug_logging(INSTANCE(c), "fmi2SetDebugLogging", loggingOn,
                                               nCategories, categories);
}

/* ---------------------------------------------------------------- life cycle */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    const char *name = instanceName ? instanceName : "";
    SlaveMemory memory;
    ModelInstance *inst;
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
    memory.allocate = functions->allocateMemory;
    memory.release = functions->freeMemory;
    inst = slave_instantiate(&kFmi2Interface, memory, sizeof(Fmi2Instance), name, loggingOn);
    if (inst != NULL) ((Fmi2Instance *)inst)->functions = *functions;
    return inst;
}

void fmi2FreeInstance(fmi2Component c) { slave_free(INSTANCE(c)); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    return (fmi2Status)slave_setup_experiment(INSTANCE(c), "fmi2SetupExperiment", startTime,
                                              stopTimeDefined, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    return (fmi2Status)slave_enter_initialization_mode(INSTANCE(c),
                                                       "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return (fmi2Status)slave_exit_initialization_mode(INSTANCE(c), "fmi2ExitInitializationMode",
                                                      SLAVE_STEP_MODE);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    return (fmi2Status)slave_terminate(INSTANCE(c), "fmi2Terminate");
}

fmi2Status fmi2Reset(fmi2Component c) {
    return (fmi2Status)slave_reset(INSTANCE(c), "fmi2Reset");
}

/* ---------------------------------------------------------------- variable access */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    return (fmi2Status)slave_get_values(INSTANCE(c), "fmi2GetReal", VARIABLE_REAL, vr, nvr, value,
                                        nvr);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    return (fmi2Status)slave_set_values(INSTANCE(c), "fmi2SetReal", VARIABLE_REAL, vr, nvr, value,
                                        nvr);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    return (fmi2Status)slave_get_values(INSTANCE(c), "fmi2GetInteger", VARIABLE_INTEGER, vr, nvr,
                                        value, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    return (fmi2Status)slave_set_values(INSTANCE(c), "fmi2SetInteger", VARIABLE_INTEGER, vr, nvr,
                                        value, nvr);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return (fmi2Status)slave_no_variables_of_type(INSTANCE(c), "fmi2GetBoolean", nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return (fmi2Status)slave_no_variables_of_type(INSTANCE(c), "fmi2SetBoolean", nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)vr;
    (void)value;
    return (fmi2Status)slave_no_variables_of_type(INSTANCE(c), "fmi2GetString", nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)vr;
    (void)value;
    return (fmi2Status)slave_no_variables_of_type(INSTANCE(c), "fmi2SetString", nvr);
}

/* ---------------------------------------------------------------- stepping */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)slave_do_step(INSTANCE(c), "fmi2DoStep", currentCommunicationPoint,
                                     communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    if (!slave_allowed(INSTANCE(c), "fmi2CancelStep", SLAVE_ANY_STATE)) return fmi2Error;
    slave_log_error(INSTANCE(c), "fmi2CancelStep: doStep always completes synchronously");
    return fmi2Error;
}

static fmi2Status unsupported(fmi2Component c, const char *function) {
    return (fmi2Status)slave_unsupported(INSTANCE(c), function);
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
