/* The limit for the co-simulation master: step an FMU binary through the same
 * fmi2SetReal (2 inputs) / fmi2DoStep / fmi2GetReal (the contract's outputs) sequence as the
 * twin, with the currents read from a file instead of computed by a controller.
 * Usage: c_loop BINARY.so GUID CURRENTS.f64 STEP_S VR_IN0 VR_IN1 VR_OUT0 [VR_OUT1 ...] (at most
 * MAX_OUTPUTS outputs)
 * Prints the wall time of the stepping loop in seconds. */
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "fmi2Functions.h"

#define MAX_OUTPUTS 8

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    (void)name;
    (void)status;
    (void)category;
    fprintf(stderr, "%s\n", message);
}

int main(int argc, char *argv[]) {
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2ValueReference vr_in[2], vr_out[MAX_OUTPUTS];
    fmi2Real inputs[2] = {0.0, 0.0}, outputs[MAX_OUTPUTS];
    double h, *currents, elapsed;
    long n, k, n_out = argc - 7;
    FILE *file;
    void *library;
    struct timespec start, stop;
    if (n_out < 1 || n_out > MAX_OUTPUTS) return 1;
    h = atof(argv[4]);
    vr_in[0] = (fmi2ValueReference)atoi(argv[5]);
    vr_in[1] = (fmi2ValueReference)atoi(argv[6]);
    for (k = 0; k < n_out; k++) vr_out[k] = (fmi2ValueReference)atoi(argv[7 + k]);
    file = fopen(argv[3], "rb");
    if (!file) return 2;
    fseek(file, 0, SEEK_END);
    n = ftell(file) / (long)sizeof(double);
    rewind(file);
    currents = malloc((size_t)n * sizeof(double));
    if (!currents || fread(currents, sizeof(double), (size_t)n, file) != (size_t)n) return 3;
    fclose(file);
    library = dlopen(argv[1], RTLD_NOW);
    if (!library) return 4;
    {
        fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)dlsym(library, "fmi2Instantiate");
        fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)dlsym(library, "fmi2SetupExperiment");
        fmi2EnterInitializationModeTYPE *enter =
            (fmi2EnterInitializationModeTYPE *)dlsym(library, "fmi2EnterInitializationMode");
        fmi2ExitInitializationModeTYPE *exit_init =
            (fmi2ExitInitializationModeTYPE *)dlsym(library, "fmi2ExitInitializationMode");
        fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)dlsym(library, "fmi2SetReal");
        fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)dlsym(library, "fmi2GetReal");
        fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)dlsym(library, "fmi2DoStep");
        fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)dlsym(library, "fmi2FreeInstance");
        fmi2Component c = instantiate("c_loop", fmi2CoSimulation, argv[2], "", &callbacks, fmi2False, fmi2False);
        if (!c || setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK || enter(c) != fmi2OK ||
            exit_init(c) != fmi2OK) return 5;
        clock_gettime(CLOCK_MONOTONIC, &start);
        for (k = 0; k < n; k++) {
            inputs[0] = currents[k];
            if (set_real(c, vr_in, 2, inputs) != fmi2OK) return 6;
            if (do_step(c, k * h, h, fmi2True) != fmi2OK) return 7;
            if (get_real(c, vr_out, (size_t)n_out, outputs) != fmi2OK) return 8;
        }
        clock_gettime(CLOCK_MONOTONIC, &stop);
        free_instance(c);
    }
    elapsed = (double)(stop.tv_sec - start.tv_sec) + 1e-9 * (double)(stop.tv_nsec - start.tv_nsec);
    printf("%.9f\n", elapsed);
    free(currents);
    dlclose(library);
    return 0;
}
