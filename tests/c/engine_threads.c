/* Test program of the C engine (tests/test_c_engine.py writes model_data.h and builds
 * this with a model's kernels and the engine's sources, no LAPACK, no Python).
 *
 * One model and one sparse pattern (the constants) serve three instances: the first
 * runs RK4 with projection alone, then the other two run the same at once in two
 * threads that start together. Each instance counts the heap allocations its thread
 * makes from the run's start to its end (malloc, calloc, realloc and free are wrapped
 * at link time: -Wl,--wrap=...), and the main thread those of the instances' set-up
 * (which allocates: the counter works). Prints that count, what an engine without
 * LAPACK says when asked for the dense path, then per instance its status, its count,
 * and every record's q and v as hexadecimal floats. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fcc_rk4.h"
#include "kernels.h"
#include "model_data.h"

#define ALLOC_COUNT_STORAGE static __thread   /* each thread's calls, while counting */
#include "alloc_count.h"

typedef struct instance {
    fcc_assembly a;
    fcc_engine e;
    fcc_rk4 r;
    int status;
    long allocations;
    pthread_barrier_t *start;   /* NULL: run alone */
} instance;

static fcc_model model;
static fcc_pattern pattern;

static void die(const char *what)
{
    fprintf(stderr, "%s\n", what);
    exit(2);
}

static void set_up(instance *in)
{
    fcc_settings s;
    long n_rec = 1 + N_STEPS / EVERY + (N_STEPS % EVERY ? 1 : 0);
    s.rank_tol = RANK_TOL;
    s.position_tol = POSITION_TOL;
    s.max_newton = MAX_NEWTON;
    s.grow_tol = GROW_TOL;
    s.decide_tol = DECIDE_TOL;
    s.ambiguous_low = AMBIGUOUS_LOW;
    s.row_floor = ROW_FLOOR;
    if (fcc_assembly_init(&in->a, &model, PARAMS) != FCC_OK
            || fcc_engine_init(&in->e, &in->a, NULL, &s) != FCC_OK
            || fcc_sparse_init(&in->e, &pattern) != FCC_OK)
        die("set-up failed");
    in->e.sp.beyond_quotient = BEYOND_QUOTIENT;
    fcc_engine_decide_rank(&in->e, RANK);
    memset(&in->r, 0, sizeof(in->r));       /* settings not named below: none (NULL) */
    in->r.project = 1;
    in->r.baumgarte = 0;
    in->r.alpha = in->r.beta = 0.0;
    in->r.n_steps = N_STEPS;
    in->r.every = EVERY;
    in->r.dt = DT;
    in->r.t_end = T_END;
    in->r.out.t = calloc((size_t)n_rec, sizeof(double));
    in->r.out.q = calloc((size_t)n_rec * N_Q, sizeof(double));
    in->r.out.v = calloc((size_t)n_rec * N_Q, sizeof(double));
    in->r.out.body = calloc((size_t)n_rec * 6 * (N_BODIES + 1), sizeof(double));
    in->r.out.energy = calloc((size_t)n_rec, sizeof(double));
    in->r.out.cerr = calloc((size_t)n_rec, sizeof(double));
    in->r.ev = NULL;
    in->r.saved = NULL;
    in->r.dense = NULL;
    in->r.pause = NULL;
    in->r.pause_ctx = NULL;
}

static void *run(void *arg)
{
    instance *in = arg;
    if (in->start != NULL)
        pthread_barrier_wait(in->start);
    allocations = 0;
    counting = 1;
    in->status = fcc_rk4_start(&in->r, &in->e, Q0, V0);
    if (in->status == 0) {
        fcc_rk4_record(&in->e, &in->r, 0.0);
        in->status = fcc_rk4_advance(&in->e, &in->r);
    }
    fcc_run_finish(&in->e);
    counting = 0;
    in->allocations = allocations;
    return NULL;
}

static void report(const char *name, instance *in)
{
    long j;
    int i;
    printf("instance %s status %d allocations %ld records %ld\n", name, in->status,
           in->allocations, in->r.n_out);
    if (in->status != FCC_RUN_DONE)
        printf("message %s\n", fcc_engine_message(&in->e));
    for (j = 0; j < in->r.n_out; j++) {
        printf("record %s %ld", name, j);
        for (i = 0; i < N_Q; i++)
            printf(" %a", in->r.out.q[j * N_Q + i]);
        for (i = 0; i < N_Q; i++)
            printf(" %a", in->r.out.v[j * N_Q + i]);
        printf("\n");
    }
}

int main(void)
{
    instance in[3];
    pthread_t threads[2];
    pthread_barrier_t start;
    int i;
    if (fcc_model_init(&model, &TABLE, N_Q, N_EL, CLASS_OF, Q_PTR, Q_IDX, P_PTR,
                       N_BODIES, BODY_ELEMENTS, N_TIME, TIME_SLOTS) != FCC_OK
            || fcc_pattern_init(&pattern, &model) != FCC_OK)
        die("model set-up failed");
#if HAS_VIEW
    if (fcc_pattern_set_view(&pattern, SNQ, SLOC, SNG, SRLOC, EFIX, N_PINNED, PINNED,
                             N_FIXED_ROWS, FIXED_ROWS, FIXED_NORM, FIXED_G_TOL, N_FIXED,
                             FIXED_OFF, FIXED_VAL, FIXED_TOL) != FCC_OK)
        die("view failed");
#endif
    if (fcc_pattern_set_guards(&pattern, N_ZERO_M, ZERO_M, ZERO_M_TOL, N_ZERO_B, ZERO_B,
                               ZERO_B_TOL) != FCC_OK
            || fcc_pattern_set_structure(&pattern, PERM, AP, AI, ENT_PTR, ENT_A, ENT_B,
                                         ENT_POS) != FCC_OK)
        die("pattern failed");
    counting = 1;                            /* the counter sees the set-up's */
    for (i = 0; i < 3; i++) {
        set_up(&in[i]);
        in[i].start = i ? &start : NULL;
    }
    counting = 0;
    printf("setup allocations %ld\n", allocations);
    run(&in[0]);
    pthread_barrier_init(&start, NULL, 2);
    for (i = 0; i < 2; i++)
        if (pthread_create(&threads[i], NULL, run, &in[i + 1]) != 0)
            die("no thread");
    for (i = 0; i < 2; i++)
        pthread_join(threads[i], NULL);
    /* an engine without LAPACK on the dense path: the documented error */
    {
        fcc_assembly a;
        fcc_engine dense;
        double acc[N_Q];
        fcc_settings s = in[0].e.set;
        int rc;
        if (fcc_assembly_init(&a, &model, PARAMS) != FCC_OK
                || fcc_engine_init(&dense, &a, NULL, &s) != FCC_OK)
            die("dense set-up failed");
        rc = fcc_accelerations(&dense, Q0, V0, acc, 0);
        printf("dense_without_lapack %d %d %s\n", rc, dense.err,
               fcc_engine_message(&dense));
        fcc_engine_free(&dense);
        fcc_assembly_free(&a);
    }
    report("alone", &in[0]);
    report("thread1", &in[1]);
    report("thread2", &in[2]);
    for (i = 0; i < 3; i++) {
        fcc_engine_free(&in[i].e);
        fcc_assembly_free(&in[i].a);
    }
    fcc_pattern_free(&pattern);
    fcc_model_free(&model);
    return 0;
}
