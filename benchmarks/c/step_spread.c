/* Per-step times of an exported model on the thread's CPU clock
 * (benchmarks/step_time_spread.py builds this with the model's library:
 * -DMODEL=name -DHEADER=name.h).
 *
 *   ./spread REPEATS
 *
 * Runs the model's whole simulate: run REPEATS times after a warm-up run, one
 * step_to of one dt at a time. Each step is timed with CLOCK_THREAD_CPUTIME_ID (the
 * CPU this thread spent: a preemption by another process does not count) and with
 * CLOCK_MONOTONIC (wall time, for comparison). A step whose event log grew (the
 * events located and acted on inside it: a latch's lock, an impact) is marked.
 * To say where a step's time goes, the harness is built with the model's API source
 * (-DAPI_SOURCE=name_api.c, included below, so that it reads the instance's engine
 * counters) and also prints per step the augmented-Lagrangian refinement's
 * iterations (the sparse solves' inner iterations) and the acceleration evaluations
 * (4 per plain RK4 step; an event's location re-integrates partial steps).
 * Prints per repeat one line "run R", then per step
 * "CPU_NS WALL_NS EVENTS AL_ITERATIONS RHS_EVALUATIONS". */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define STR2(x) #x
#define STR(x) STR2(x)
#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define API(f) CAT(MODEL, CAT(_, f))
#include STR(API_SOURCE)

static long long ns(clockid_t clock)
{
    struct timespec ts;
    clock_gettime(clock, &ts);
    return (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

int main(int argc, char **argv)
{
    int repeats = argc > 1 ? atoi(argv[1]) : 3, r;
    double t_end = API(t_end)(), dt = API(dt)();
    long n = (long)(t_end / dt + 0.5), k;
    long long *cpu = malloc((size_t)n * sizeof *cpu), *wall = malloc((size_t)n * sizeof *wall);
    int *events = malloc((size_t)n * sizeof *events);
    long *iters = malloc((size_t)n * sizeof *iters), *rhs = malloc((size_t)n * sizeof *rhs);
    API(sim) *sim = API(create)();
    if (sim == NULL || cpu == NULL || wall == NULL || events == NULL || iters == NULL
            || rhs == NULL)
        return 2;
    for (r = -1; r < repeats; r++) {          /* r = -1: the warm-up */
        if (API(start)(sim, t_end) != 0)
            return 3;
        for (k = 1; k <= n; k++) {
            long before = API(event_count)(sim) + API(events_dropped)(sim);
            long it0 = sim->e.sp.n_iterations, rhs0 = sim->r.n_rhs;
            long long c0 = ns(CLOCK_THREAD_CPUTIME_ID), w0 = ns(CLOCK_MONOTONIC);
            int rc = API(step_to)(sim, k < n ? k * dt : t_end);
            long long w1 = ns(CLOCK_MONOTONIC), c1 = ns(CLOCK_THREAD_CPUTIME_ID);
            if (rc != 0) {
                fprintf(stderr, "%s\n", rc < 0 ? API(message)(sim) : "a stop event");
                return 4;
            }
            cpu[k - 1] = c1 - c0;
            wall[k - 1] = w1 - w0;
            events[k - 1] = (int)(API(event_count)(sim) + API(events_dropped)(sim) - before);
            iters[k - 1] = sim->e.sp.n_iterations - it0;
            rhs[k - 1] = sim->r.n_rhs - rhs0;
        }
        if (r < 0)
            continue;
        printf("run %d\n", r);
        for (k = 0; k < n; k++)
            printf("%lld %lld %d %ld %ld\n", cpu[k], wall[k], events[k], iters[k], rhs[k]);
    }
    API(destroy)(sim);
    free(cpu);
    free(wall);
    free(events);
    free(iters);
    free(rhs);
    return 0;
}
