/* FMI 3.0 co-simulation API shared by every model of this project.
 *
 * Thin API functions, as in fmi2_slave.c: each one translates its arguments and hands over to
 * the slave shared by both versions (slave.c), which checks the instance, the state machine and
 * the arguments, then goes to the variable table or to a model hook. What only FMI 3.0 has lives
 * here: the instantiation token, the event mode (entered only when the importer asks for it at
 * instantiation; the model never signals an event) and the outputs of fmi3DoStep. Every failure
 * returns fmi3Error with a message through the importer's logger; nothing aborts the process.
 *
 * A compiled loop may call fmi3SetFloat64, fmi3DoStep and fmi3GetFloat64 by address: they take
 * plain arrays and pointers and never call back into the importer except to log an error.
 */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "slave.h"

/* The shared slave's statuses are this version's: its functions return them cast. */
typedef char slave_status_is_fmi3_status[
    (int)SLAVE_OK == (int)fmi3OK && (int)SLAVE_ERROR == (int)fmi3Error ? 1 : -1];

/* An instance: the shared slave's data, then what the importer gave at instantiation. */
typedef struct {
    ModelInstance model;                    /* first: what slave.c works on */
    fmi3InstanceEnvironment environment;    /* passed back to the logger */
    fmi3LogMessageCallback log_message;     /* NULL: the importer takes no messages */
    int event_mode_used;                    /* 1: the importer steps through event mode */
} Fmi3Instance;

static void log_to_importer(const ModelInstance *inst, SlaveStatus status, const char *category,
                            const char *message) {
    const Fmi3Instance *instance = (const Fmi3Instance *)inst;
    if (instance->log_message == NULL) return;
    instance->log_message(instance->environment, (fmi3Status)status, category, message);
}

static const SlaveInterface kFmi3Interface = {
    .log = log_to_importer,
    .state_names = {
        [SLAVE_INSTANTIATED] = "Instantiated",
        [SLAVE_INITIALIZATION_MODE] = "InitializationMode",
        [SLAVE_STEP_MODE] = "StepMode",
        [SLAVE_EVENT_MODE] = "EventMode",
        [SLAVE_TERMINATED] = "Terminated",
        [SLAVE_ERROR_STATE] = "Error",
    },
    .real_type = "Float64",
    .integer_type = "Int32",
    .declares_time = 1,
};

/* FMI 3.0 leaves memory to the FMU: the C library's. */
static const SlaveMemory kMemory = {calloc, free};

#define INSTANCE(instance) ((ModelInstance *)(instance))

/* 1 when every output pointer of a call is set; else logs and returns 0. */
static int outputs_given(ModelInstance *inst, const char *function, int all_given) {
    if (all_given) return 1;
    slave_log_error(inst, "%s: an output argument is NULL", function);
    return 0;
}

/* ---------------------------------------------------------------- inquiry and logging */

const char *fmi3GetVersion(void) { return fmi3Version; }

/* Enables or disables the named categories (all of them when nCategories is 0). Errors stay
 * logged whatever is chosen here. */
fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    return (fmi3Status)slave_set_debug_logging(INSTANCE(instance), "fmi3SetDebugLogging",
                                               loggingOn, nCategories, categories);
}

/* ---------------------------------------------------------------- life cycle */

/* Says through the importer's logger, if any, why no instance is made; NULL. */
static fmi3Instance refuse(fmi3InstanceEnvironment environment, fmi3LogMessageCallback log,
                           const char *message) {
    if (log != NULL) log(environment, fmi3Error, "logStatusError", message);
    return NULL;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    return refuse(instanceEnvironment, logMessage,
                  "fmi3InstantiateModelExchange: only co-simulation is supported");
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName,
                                         fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible,
                                         fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Fmi3Instance *instance;
    /* No early return and no intermediate update: doStep always completes its step. */
    (void)resourcePath;
    (void)visible;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (instantiationToken == NULL || strcmp(instantiationToken, MODEL_GUID) != 0) {
        return refuse(instanceEnvironment, logMessage, "fmi3InstantiateCoSimulation: "
                      "instantiationToken does not match this binary");
    }
    instance = (Fmi3Instance *)slave_instantiate(&kFmi3Interface, kMemory, sizeof(Fmi3Instance),
                                                 instanceName ? instanceName : "", loggingOn);
    if (instance == NULL) return NULL;
    instance->environment = instanceEnvironment;
    instance->log_message = logMessage;
    instance->event_mode_used = eventModeUsed;
    return instance;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName,
                                               fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    return refuse(instanceEnvironment, logMessage,
                  "fmi3InstantiateScheduledExecution: only co-simulation is supported");
}

void fmi3FreeInstance(fmi3Instance instance) { slave_free(INSTANCE(instance)); }

/* Sets up the experiment (FMI 2.0's fmi2SetupExperiment) and enters initialization mode. */
fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    const char *function = "fmi3EnterInitializationMode";
    (void)toleranceDefined;
    (void)tolerance;
    if (slave_setup_experiment(INSTANCE(instance), function, startTime, stopTimeDefined,
                               stopTime) != SLAVE_OK) {
        return fmi3Error;
    }
    return (fmi3Status)slave_enter_initialization_mode(INSTANCE(instance), function);
}

/* On to step mode, or to event mode when the importer instantiated with eventModeUsed. */
fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    const Fmi3Instance *fmi3 = (const Fmi3Instance *)instance;
    SlaveState next = fmi3 != NULL && fmi3->event_mode_used ? SLAVE_EVENT_MODE : SLAVE_STEP_MODE;
    return (fmi3Status)slave_exit_initialization_mode(INSTANCE(instance),
                                                      "fmi3ExitInitializationMode", next);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    const char *function = "fmi3EnterEventMode";
    if (!slave_allowed(INSTANCE(instance), function, SLAVE_IN(SLAVE_STEP_MODE))) return fmi3Error;
    if (!((const Fmi3Instance *)instance)->event_mode_used) {
        slave_log_error(INSTANCE(instance), "%s: the instance was created with eventModeUsed = "
                        "false", function);
        return fmi3Error;
    }
    INSTANCE(instance)->state = SLAVE_EVENT_MODE;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    return (fmi3Status)slave_terminate(INSTANCE(instance), "fmi3Terminate");
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    return (fmi3Status)slave_reset(INSTANCE(instance), "fmi3Reset");
}

/* ---------------------------------------------------------------- variable access */

/* The getter and setter of a type the model has variables of: Float64 (the table's Reals)
 * and Int32 (its Integers). */
#define VARIABLES_OF_TYPE(Type, Value, table_type)                                              \
    fmi3Status fmi3Get##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, Value values[], size_t nValues) {         \
        return (fmi3Status)slave_get_values(INSTANCE(instance), "fmi3Get" #Type, table_type,   \
                                            valueReferences, nValueReferences, values,          \
                                            nValues);                                           \
    }                                                                                           \
    fmi3Status fmi3Set##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, const Value values[], size_t nValues) {   \
        return (fmi3Status)slave_set_values(INSTANCE(instance), "fmi3Set" #Type, table_type,   \
                                            valueReferences, nValueReferences, values,          \
                                            nValues);                                           \
    }

VARIABLES_OF_TYPE(Float64, fmi3Float64, VARIABLE_REAL)
VARIABLES_OF_TYPE(Int32, fmi3Int32, VARIABLE_INTEGER)

/* ---------------------------------------------------------------- event mode */

/* The model has no discrete states that an event could change: nothing to update, no next
 * event, no request to stop. */
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    const char *function = "fmi3UpdateDiscreteStates";
    if (!slave_allowed(INSTANCE(instance), function, SLAVE_IN(SLAVE_EVENT_MODE)) ||
        !outputs_given(INSTANCE(instance), function,
                       discreteStatesNeedUpdate && terminateSimulation &&
                           nominalsOfContinuousStatesChanged && valuesOfContinuousStatesChanged &&
                           nextEventTimeDefined && nextEventTime)) {
        return fmi3Error;
    }
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    if (!slave_allowed(INSTANCE(instance), "fmi3EnterStepMode", SLAVE_IN(SLAVE_EVENT_MODE))) {
        return fmi3Error;
    }
    INSTANCE(instance)->state = SLAVE_STEP_MODE;
    return fmi3OK;
}

/* ---------------------------------------------------------------- stepping */

/* One whole step (the model never returns early, never needs event handling and never asks to
 * stop); lastSuccessfulTime is the model time after the call, the step's end when it
 * succeeded. */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    const char *function = "fmi3DoStep";
    SlaveStatus status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!slave_allowed(INSTANCE(instance), function, SLAVE_IN(SLAVE_STEP_MODE)) ||
        !outputs_given(INSTANCE(instance), function, eventHandlingNeeded && terminateSimulation &&
                                                         earlyReturn && lastSuccessfulTime)) {
        return fmi3Error;
    }
    status = slave_do_step(INSTANCE(instance), function, currentCommunicationPoint,
                           communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = INSTANCE(instance)->time;
    return (fmi3Status)status;
}

/* ---------------------------------------------------------------- not offered
 *
 * Variables of the other types, clocks, FMU states, derivatives, configuration mode, model
 * exchange and scheduled execution: each function says so through the logger and returns
 * fmi3Error, except the getters and setters of no variables at all, which succeed. */

static fmi3Status unsupported(fmi3Instance instance, const char *function) {
    return (fmi3Status)slave_unsupported(INSTANCE(instance), function);
}

static fmi3Status no_variables(fmi3Instance instance, const char *function, size_t count) {
    return (fmi3Status)slave_no_variables_of_type(INSTANCE(instance), function, count);
}

/* The getter and setter of a type the model has no variables of. */
#define NO_VARIABLES_OF_TYPE(Type, Value)                                                       \
    fmi3Status fmi3Get##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, Value values[], size_t nValues) {         \
        (void)valueReferences;                                                                  \
        (void)values;                                                                           \
        (void)nValues;                                                                          \
        return no_variables(instance, "fmi3Get" #Type, nValueReferences);                       \
    }                                                                                           \
    fmi3Status fmi3Set##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, const Value values[], size_t nValues) {   \
        (void)valueReferences;                                                                  \
        (void)values;                                                                           \
        (void)nValues;                                                                          \
        return no_variables(instance, "fmi3Set" #Type, nValueReferences);                       \
    }

NO_VARIABLES_OF_TYPE(Float32, fmi3Float32)
NO_VARIABLES_OF_TYPE(Int8, fmi3Int8)
NO_VARIABLES_OF_TYPE(UInt8, fmi3UInt8)
NO_VARIABLES_OF_TYPE(Int16, fmi3Int16)
NO_VARIABLES_OF_TYPE(UInt16, fmi3UInt16)
NO_VARIABLES_OF_TYPE(UInt32, fmi3UInt32)
NO_VARIABLES_OF_TYPE(Int64, fmi3Int64)
NO_VARIABLES_OF_TYPE(UInt64, fmi3UInt64)
NO_VARIABLES_OF_TYPE(Boolean, fmi3Boolean)
NO_VARIABLES_OF_TYPE(String, fmi3String)

/* Binary variables carry a size per value. */
#define NO_BINARY_VARIABLES(Name, Const)                                                        \
    fmi3Status fmi3##Name(fmi3Instance instance, const fmi3ValueReference valueReferences[],    \
                          size_t nValueReferences, Const size_t valueSizes[],                   \
                          Const fmi3Binary values[], size_t nValues) {                          \
        (void)valueReferences;                                                                  \
        (void)valueSizes;                                                                       \
        (void)values;                                                                           \
        (void)nValues;                                                                          \
        return no_variables(instance, "fmi3" #Name, nValueReferences);                          \
    }

NO_BINARY_VARIABLES(GetBinary, )
NO_BINARY_VARIABLES(SetBinary, const)

/* Clocks: the model has none. Their values, intervals and shifts come in one array per clock
 * or in two. */
#define NO_CLOCKS(Name, Values)                                                                 \
    fmi3Status fmi3##Name(fmi3Instance instance, const fmi3ValueReference valueReferences[],    \
                          size_t nValueReferences, Values values[]) {                           \
        (void)valueReferences;                                                                  \
        (void)values;                                                                           \
        return no_variables(instance, "fmi3" #Name, nValueReferences);                          \
    }
#define NO_CLOCK_PAIRS(Name, First, Second)                                                     \
    fmi3Status fmi3##Name(fmi3Instance instance, const fmi3ValueReference valueReferences[],    \
                          size_t nValueReferences, First first[], Second second[]) {            \
        (void)valueReferences;                                                                  \
        (void)first;                                                                            \
        (void)second;                                                                           \
        return no_variables(instance, "fmi3" #Name, nValueReferences);                          \
    }

NO_CLOCKS(GetClock, fmi3Clock)
NO_CLOCKS(SetClock, const fmi3Clock)
NO_CLOCKS(GetShiftDecimal, fmi3Float64)
NO_CLOCKS(SetShiftDecimal, const fmi3Float64)
NO_CLOCKS(SetIntervalDecimal, const fmi3Float64)
NO_CLOCK_PAIRS(GetIntervalDecimal, fmi3Float64, fmi3IntervalQualifier)
NO_CLOCK_PAIRS(GetShiftFraction, fmi3UInt64, fmi3UInt64)
NO_CLOCK_PAIRS(SetShiftFraction, const fmi3UInt64, const fmi3UInt64)
NO_CLOCK_PAIRS(SetIntervalFraction, const fmi3UInt64, const fmi3UInt64)

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return no_variables(instance, "fmi3GetIntervalFraction", nValueReferences);
}

/* Functions of the instance alone. */
#define NOT_OFFERED(Name)                                                                       \
    fmi3Status fmi3##Name(fmi3Instance instance) { return unsupported(instance, "fmi3" #Name); }

NOT_OFFERED(EnterConfigurationMode)
NOT_OFFERED(ExitConfigurationMode)
NOT_OFFERED(EvaluateDiscreteStates)
NOT_OFFERED(EnterContinuousTimeMode)

/* Functions with one output or input argument of the instance: a count, a time or an FMU
 * state. */
#define NOT_OFFERED_WITH(Name, Argument)                                                        \
    fmi3Status fmi3##Name(fmi3Instance instance, Argument) {                                    \
        (void)argument;                                                                         \
        return unsupported(instance, "fmi3" #Name);                                             \
    }

NOT_OFFERED_WITH(GetNumberOfEventIndicators, size_t *argument)
NOT_OFFERED_WITH(GetNumberOfContinuousStates, size_t *argument)
NOT_OFFERED_WITH(SetTime, fmi3Float64 argument)
NOT_OFFERED_WITH(GetFMUState, fmi3FMUState *argument)
NOT_OFFERED_WITH(SetFMUState, fmi3FMUState argument)
NOT_OFFERED_WITH(FreeFMUState, fmi3FMUState *argument)

/* Model-exchange arrays of the continuous states or event indicators. */
#define NOT_OFFERED_ARRAY(Name, Values)                                                         \
    fmi3Status fmi3##Name(fmi3Instance instance, Values values[], size_t nValues) {            \
        (void)values;                                                                           \
        (void)nValues;                                                                          \
        return unsupported(instance, "fmi3" #Name);                                             \
    }

NOT_OFFERED_ARRAY(GetContinuousStateDerivatives, fmi3Float64)
NOT_OFFERED_ARRAY(GetEventIndicators, fmi3Float64)
NOT_OFFERED_ARRAY(GetContinuousStates, fmi3Float64)
NOT_OFFERED_ARRAY(GetNominalsOfContinuousStates, fmi3Float64)
NOT_OFFERED_ARRAY(SetContinuousStates, const fmi3Float64)

/* The directional and the adjoint derivative take the same arguments. */
#define NOT_OFFERED_DERIVATIVE(Name)                                                            \
    fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference unknowns[],        \
                             size_t nUnknowns, const fmi3ValueReference knowns[],               \
                             size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,            \
                             fmi3Float64 sensitivity[], size_t nSensitivity) {                  \
        (void)unknowns;                                                                         \
        (void)nUnknowns;                                                                        \
        (void)knowns;                                                                           \
        (void)nKnowns;                                                                          \
        (void)seed;                                                                             \
        (void)nSeed;                                                                            \
        (void)sensitivity;                                                                      \
        (void)nSensitivity;                                                                     \
        return unsupported(instance, "fmi3Get" #Name);                                          \
    }

NOT_OFFERED_DERIVATIVE(DirectionalDerivative)
NOT_OFFERED_DERIVATIVE(AdjointDerivative)

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    (void)FMUState;
    (void)size;
    return unsupported(instance, "fmi3SerializedFMUStateSize");
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    (void)FMUState;
    (void)serializedState;
    (void)size;
    return unsupported(instance, "fmi3SerializeFMUState");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    (void)serializedState;
    (void)size;
    (void)FMUState;
    return unsupported(instance, "fmi3DeserializeFMUState");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return unsupported(instance, "fmi3GetVariableDependencies");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return unsupported(instance, "fmi3CompletedIntegratorStep");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance,
                                    const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)orders;
    (void)values;
    (void)nValues;
    return unsupported(instance, "fmi3GetOutputDerivatives");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    return unsupported(instance, "fmi3ActivateModelPartition");
}
