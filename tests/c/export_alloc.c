/* Test program of an exported model (tests/test_export_c.py): counts the heap
 * allocation calls (malloc, calloc, realloc, free wrapped at link time) made from a
 * run's start to its end, through the API only. Model: MODEL (a -D of the build).
 * Prints "allocations N steps K energy E". */
#include <stdio.h>
#include <stdlib.h>

#define STR2(x) #x
#define STR(x) STR2(x)
#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define API(f) CAT(MODEL, CAT(_, f))
#include STR(HEADER)

#include "alloc_count.h"

int main(void)
{
    API(sim) *sim;
    long k, n;
    double energy = 0.0, values[4096];
    counting = 1;
    sim = API(create)();            /* set-up allocates: the counter must see it */
    counting = 0;
    printf("setup %ld\n", allocations);
    if (sim == NULL || API(output_count)() > 4096)
        return 2;
    allocations = 0;
    counting = 1;
    if (API(start)(sim, API(t_end)()) != 0)
        return 3;
    n = (long)(API(t_end)() / API(dt)() + 0.5);
    for (k = 1; k <= n; k++) {
        if (API(step_to)(sim, k < n ? k * API(dt)() : API(t_end)()) != 0)
            return 4;
        if (API(outputs)(sim, values) != 0)
            return 5;
    }
    energy = API(output)(sim, API(output_index)("energy"));
    counting = 0;
    printf("allocations %ld steps %ld energy %.17g\n", allocations, n, energy);
    API(destroy)(sim);
    return 0;
}
