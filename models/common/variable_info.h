/* Types of the generated variable table (model_variable_table.h): one row per model variable,
 * indexed by value reference. */
#ifndef VARIABLE_INFO_H
#define VARIABLE_INFO_H

#include <stddef.h>

typedef enum {
    VARIABLE_REAL,      /* a double in ModelVariables; FMI 2.0 Real, FMI 3.0 Float64 */
    VARIABLE_INTEGER    /* an int in ModelVariables; FMI 2.0 Integer, FMI 3.0 Int32 */
} VariableType;

typedef enum {
    CAUSALITY_PARAMETER,
    CAUSALITY_INPUT,
    CAUSALITY_OUTPUT
} Causality;

typedef struct {
    const char *name;
    VariableType type;
    Causality causality;
    size_t offset;     /* byte offset of the value inside ModelVariables */
    double start;      /* an Integer's start and limits are whole numbers */
    double min;        /* inclusive lower limit: -INFINITY (INT_MIN for an Integer) when none */
    double max;        /* inclusive upper limit: +INFINITY (INT_MAX for an Integer) when none */
    int positive;      /* 1: a Real must be strictly greater than zero */
} VariableInfo;

#endif
