/* Types of the generated variable tables (model_variables.h). One row per model variable. */
#ifndef VARIABLE_INFO_H
#define VARIABLE_INFO_H

#include <stddef.h>

typedef enum {
    CAUSALITY_PARAMETER,
    CAUSALITY_INPUT,
    CAUSALITY_OUTPUT
} Causality;

typedef struct {
    const char *name;
    Causality causality;
    size_t offset;     /* byte offset of the value inside ModelVariables */
    double start;
    double min;        /* inclusive lower limit, -INFINITY when none */
    double max;        /* inclusive upper limit, +INFINITY when none */
    int positive;      /* 1: the value must be strictly greater than zero */
} RealVariableInfo;

typedef struct {
    const char *name;
    Causality causality;
    size_t offset;
    int start;
    int min;
    int max;
} IntegerVariableInfo;

#endif
