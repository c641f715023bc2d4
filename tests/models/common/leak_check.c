/* Instantiate / initialise / step / reset / free cycles of an FMU binary, for valgrind.
 * Usage: leak_check BINARY.so GUID CYCLES. Exits non-zero on an unexpected fmi2 status. */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    (void)name;
    (void)status;
    (void)category;
    (void)message;
}

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(library, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 2; }
#define EXPECT(call, status) if ((call) != (status)) { fprintf(stderr, "%s\n", #call); return 3; }

int main(int argc, char *argv[]) {
    void *library;
    int cycles, i, k;
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2ValueReference vr_current = 0;
    fmi2Real current = 1.0, bad = -1.0, value = 0.0;
    fmi2String events = "logEvents", unknown = "logNothing";
    if (argc != 4) return 1;
    cycles = atoi(argv[3]);
    library = dlopen(argv[1], RTLD_NOW);
    if (!library) return 2;
    {
        LOAD(fmi2Instantiate) LOAD(fmi2FreeInstance) LOAD(fmi2SetupExperiment)
        LOAD(fmi2EnterInitializationMode) LOAD(fmi2ExitInitializationMode) LOAD(fmi2DoStep)
        LOAD(fmi2SetReal) LOAD(fmi2GetReal) LOAD(fmi2Reset) LOAD(fmi2Terminate)
        LOAD(fmi2SetDebugLogging)
        fmi2Component c = NULL;
        for (i = 0; i < cycles; i++) {
            c = fmi2Instantiate("leak", fmi2CoSimulation, argv[2], "", &callbacks, fmi2False, fmi2False);
            if (!c) return 4;
            EXPECT(fmi2SetDebugLogging(c, fmi2True, 1, &events), fmi2OK)
            EXPECT(fmi2SetDebugLogging(c, fmi2True, 1, &unknown), fmi2Error)
            for (k = 0; k < 2; k++) {
                EXPECT(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK)
                EXPECT(fmi2EnterInitializationMode(c), fmi2OK)
                EXPECT(fmi2ExitInitializationMode(c), fmi2OK)
                EXPECT(fmi2SetReal(c, &vr_current, 1, &current), fmi2OK)
                EXPECT(fmi2DoStep(c, 0.0, 62.5e-6, fmi2True), fmi2OK)
                EXPECT(fmi2GetReal(c, &vr_current, 1, &value), fmi2OK)
                EXPECT(fmi2DoStep(c, 1.0, 62.5e-6, fmi2True), fmi2Error) /* not the model time */
                EXPECT(fmi2DoStep(c, -1.0, -1.0, fmi2True), fmi2Error) /* logged error path */
                EXPECT(fmi2Reset(c), fmi2OK)
            }
            EXPECT(fmi2SetReal(c, &vr_current, 1, &bad), fmi2OK)
            EXPECT(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK)
            EXPECT(fmi2EnterInitializationMode(c), fmi2OK)
            EXPECT(fmi2ExitInitializationMode(c), fmi2OK)
            EXPECT(fmi2Terminate(c), fmi2OK)
            fmi2FreeInstance(c);
        }
    }
    dlclose(library);
    return 0;
}
