/* A command input delayed by a dead time in seconds, shared by the models.
 *
 * The importer sets the command at communication points; it holds until the next one. The drive
 * acts on that held command a dead time T later: u_applied(tau) = u_cmd(tau - T), 0 before the
 * first command. The dead time does not depend on the communication step; when a delayed change
 * falls inside a step, the step is split there (command_delay_advance; solver.h drives it).
 */
#ifndef COMMAND_DELAY_H
#define COMMAND_DELAY_H

#include <math.h>

/* Commands that may still have to act: at most this many communication points per dead time. */
#define COMMAND_DELAY_CAPACITY 512

typedef struct {
    double time[COMMAND_DELAY_CAPACITY];    /* s, communication point from which value[i] held */
    double value[COMMAND_DELAY_CAPACITY];   /* the command held from time[i] on */
    int first;                              /* ring index of the oldest entry */
    int count;                              /* entries in use, at least 1 */
    double dead_time;                       /* s, from setting a command to its acting */
    double acting;                          /* the command acting on the plant now */
} CommandDelay;

/* No command yet: 0 acts from the beginning of time, a dead time (s) late. */
static inline void command_delay_reset(CommandDelay *d, double dead_time) {
    d->first = 0;
    d->count = 1;
    d->time[0] = -INFINITY;
    d->value[0] = 0.0;
    d->dead_time = dead_time;
    d->acting = 0.0;
}

static inline int command_delay_slot(const CommandDelay *d, int i) {
    return (d->first + i) % COMMAND_DELAY_CAPACITY;
}

/* Records `value`, held from time t (s) on, and forgets the commands that can no longer act,
 * within a time tolerance (s). Returns 0 when the buffer is full (more than
 * COMMAND_DELAY_CAPACITY communication points within one dead time), 1 otherwise. */
static inline int command_delay_push(CommandDelay *d, double t, double value, double tolerance) {
    while (d->count > 1 && d->time[command_delay_slot(d, 1)] + d->dead_time <= t + tolerance) {
        d->first = command_delay_slot(d, 1);
        d->count--;
    }
    if (d->count == COMMAND_DELAY_CAPACITY) return 0;
    d->time[command_delay_slot(d, d->count)] = t;
    d->value[command_delay_slot(d, d->count)] = value;
    d->count++;
    return 1;
}

/* The command acting at time tau (s): the last one set at or before tau - dead_time (within
 * the tolerance, s). *next_change receives the time (s) at which the acting command changes
 * next, +INFINITY when no later command is known. */
static inline double command_delay_at(const CommandDelay *d, double tau, double tolerance,
                                      double *next_change) {
    double dead_time = d->dead_time;   /* s */
    int i = 0;
    while (i + 1 < d->count && d->time[command_delay_slot(d, i + 1)] + dead_time <= tau + tolerance) {
        i++;
    }
    *next_change = i + 1 < d->count ? d->time[command_delay_slot(d, i + 1)] + dead_time : INFINITY;
    return d->value[command_delay_slot(d, i)];
}

/* Integrates [start, start + length] (s) in `substeps` equal substeps with `command` acting
 * (also in the buffer's `acting`); `split` is 1 when the segment starts at a command change
 * inside the step. Returns 0 on failure (the integrator logged why). */
typedef int (*CommandSegment)(void *context, double command, double start, double length,
                              int substeps, int split);

/* Advances from t (s) by h (s) with the delayed command: the step is split where the acting
 * command changes, each part integrated with as many substeps as keep the substep at most
 * h / substeps. Without a change inside the step this is one segment of `substeps` substeps.
 * `acting` holds the command of each segment while it runs, and of the last one after it.
 * Returns 0 when a segment failed. */
static inline int command_delay_advance(CommandDelay *d, double t, double h, int substeps,
                                        double tolerance, CommandSegment segment,
                                        void *context) {
    double start = t, end = t + h;
    for (;;) {
        double next_change;
        double command = command_delay_at(d, start, tolerance, &next_change);
        int whole = next_change >= end - tolerance;
        double length = whole ? (start == t ? h : end - start) : next_change - start;
        int n = (int)ceil(substeps * length / h - 1e-9);
        d->acting = command;
        if (!segment(context, command, start, length, n > 1 ? n : 1, start != t)) return 0;
        if (whole) return 1;
        start = next_change;
    }
}

#endif
