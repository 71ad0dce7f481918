/* Step times of an exported model (benchmarks/export_step.py builds this with the
 * model's library: -DMODEL=name -DHEADER=name.h). Runs the model's whole simulate:
 * run REPEATS times after a warm-up run; each step_to of one dt is timed with
 * CLOCK_MONOTONIC. Prints per repeat "run SECONDS" (the whole run), then "step" and
 * every step time of the last repeat in nanoseconds. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define STR2(x) #x
#define STR(x) STR2(x)
#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define API(f) CAT(MODEL, CAT(_, f))
#include STR(HEADER)

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv)
{
    int repeats = argc > 1 ? atoi(argv[1]) : 5, r;
    double t_end = API(t_end)(), dt = API(dt)();
    long n = (long)(t_end / dt + 0.5), k;
    double *times = malloc((size_t)n * sizeof(double)), t0, t1;
    API(sim) *sim = API(create)();
    if (sim == NULL || times == NULL)
        return 2;
    for (r = -1; r < repeats; r++) {          /* r = -1: the warm-up */
        if (API(start)(sim, t_end) != 0)
            return 3;
        t0 = now();
        for (k = 1; k <= n; k++) {
            double a = now();
            if (API(step_to)(sim, k < n ? k * dt : t_end) != 0) {
                fprintf(stderr, "%s\n", API(message)(sim));
                return 4;
            }
            times[k - 1] = now() - a;
        }
        t1 = now();
        if (r >= 0)
            printf("run %.9f\n", t1 - t0);
    }
    printf("step");
    for (k = 0; k < n; k++)
        printf(" %.0f", 1e9 * times[k]);
    printf("\n");
    API(destroy)(sim);
    free(times);
    return 0;
}
