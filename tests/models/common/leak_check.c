/* Instantiate / initialise / step / reset / free cycles of an FMU binary, for valgrind.
 * Usage: leak_check BINARY.so GUID CYCLES. Exits non-zero on an unexpected status.
 * Compiled with -DFMI_VERSION=2 or 3: the cycle is written once, over the calls of either API. */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#if FMI_VERSION == 2
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    (void)name;
    (void)status;
    (void)category;
    (void)message;
}

static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

typedef fmi2ValueReference ValueReference;
#define OK fmi2OK
#define ERROR fmi2Error
#define API(name) fmi2##name
#define INSTANTIATE(token) \
    fmi2Instantiate("leak", fmi2CoSimulation, token, "", &callbacks, fmi2False, fmi2False)
#define INITIALIZE(c) \
    (fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) == fmi2OK \
         ? fmi2EnterInitializationMode(c) : fmi2Error)
#define DO_STEP(c, t, h) fmi2DoStep(c, t, h, fmi2True)
#define SET_REAL(c, vr, value) fmi2SetReal(c, vr, 1, value)
#define GET_REAL(c, vr, value) fmi2GetReal(c, vr, 1, value)
#define LOAD_API                                                                           \
    LOAD(fmi2Instantiate) LOAD(fmi2FreeInstance) LOAD(fmi2SetupExperiment)                  \
    LOAD(fmi2EnterInitializationMode) LOAD(fmi2ExitInitializationMode) LOAD(fmi2DoStep)     \
    LOAD(fmi2SetReal) LOAD(fmi2GetReal) LOAD(fmi2Reset) LOAD(fmi2Terminate)                 \
    LOAD(fmi2SetDebugLogging)
#else
#include "fmi3Functions.h"

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                   fmi3String message) {
    (void)env;
    (void)status;
    (void)category;
    (void)message;
}

typedef fmi3ValueReference ValueReference;
#define OK fmi3OK
#define ERROR fmi3Error
#define API(name) fmi3##name
#define INSTANTIATE(token)                                                                     \
    fmi3InstantiateCoSimulation("leak", token, "", fmi3False, fmi3False, fmi3False, fmi3False, \
                                NULL, 0, NULL, logger, NULL)
#define INITIALIZE(c) fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0)
#define DO_STEP(c, t, h) fmi3DoStep(c, t, h, fmi3True, &event, &stop, &early, &reached)
#define SET_REAL(c, vr, value) fmi3SetFloat64(c, vr, 1, value, 1)
#define GET_REAL(c, vr, value) fmi3GetFloat64(c, vr, 1, value, 1)
#define LOAD_API                                                                           \
    LOAD(fmi3InstantiateCoSimulation) LOAD(fmi3FreeInstance)                                \
    LOAD(fmi3EnterInitializationMode) LOAD(fmi3ExitInitializationMode) LOAD(fmi3DoStep)     \
    LOAD(fmi3SetFloat64) LOAD(fmi3GetFloat64) LOAD(fmi3Reset) LOAD(fmi3Terminate)           \
    LOAD(fmi3SetDebugLogging)
#endif

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(library, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 2; }
#define EXPECT(call, status) if ((call) != (status)) { fprintf(stderr, "%s\n", #call); return 3; }

int main(int argc, char *argv[]) {
    void *library;
    int cycles, i, k;
    ValueReference vr_current = 0;
    double current = 1.0, bad = -1.0, value = 0.0;
    const char *events = "logEvents", *unknown = "logNothing";
#if FMI_VERSION == 3
    fmi3Boolean event, stop, early;
    fmi3Float64 reached;
#endif
    if (argc != 4) return 1;
    cycles = atoi(argv[3]);
    library = dlopen(argv[1], RTLD_NOW);
    if (!library) return 2;
    {
        LOAD_API
        void *c = NULL;
        for (i = 0; i < cycles; i++) {
            c = INSTANTIATE(argv[2]);
            if (!c) return 4;
            EXPECT(API(SetDebugLogging)(c, 1, 1, &events), OK)
            EXPECT(API(SetDebugLogging)(c, 1, 1, &unknown), ERROR)
            for (k = 0; k < 2; k++) {
                EXPECT(INITIALIZE(c), OK)
                EXPECT(API(ExitInitializationMode)(c), OK)
                EXPECT(SET_REAL(c, &vr_current, &current), OK)
                EXPECT(DO_STEP(c, 0.0, 62.5e-6), OK)
                EXPECT(GET_REAL(c, &vr_current, &value), OK)
                EXPECT(DO_STEP(c, 1.0, 62.5e-6), ERROR) /* not the model time */
                EXPECT(DO_STEP(c, -1.0, -1.0), ERROR) /* logged error path */
                EXPECT(API(Reset)(c), OK)
            }
            EXPECT(SET_REAL(c, &vr_current, &bad), OK)
            EXPECT(INITIALIZE(c), OK)
            EXPECT(API(ExitInitializationMode)(c), OK)
            EXPECT(API(Terminate)(c), OK)
            API(FreeInstance)(c);
        }
    }
    dlclose(library);
    return 0;
}
