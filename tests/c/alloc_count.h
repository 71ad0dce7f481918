/* Counting the heap calls of a test program: link with
   -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=free; every call made while
   `counting` is nonzero adds one to `allocations`. A program that counts per thread
   defines ALLOC_COUNT_STORAGE as `static __thread` before including this. */
#ifndef ALLOC_COUNT_H
#define ALLOC_COUNT_H

#include <stddef.h>

#ifndef ALLOC_COUNT_STORAGE
#define ALLOC_COUNT_STORAGE static
#endif

ALLOC_COUNT_STORAGE long allocations;
ALLOC_COUNT_STORAGE int counting;

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t size);
void *__real_realloc(void *p, size_t n);
void __real_free(void *p);
void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t n, size_t size);
void *__wrap_realloc(void *p, size_t n);
void __wrap_free(void *p);
void *__wrap_malloc(size_t n) { allocations += counting; return __real_malloc(n); }
void *__wrap_calloc(size_t n, size_t size)
{
    allocations += counting;
    return __real_calloc(n, size);
}
void *__wrap_realloc(void *p, size_t n) { allocations += counting; return __real_realloc(p, n); }
void __wrap_free(void *p) { allocations += counting; __real_free(p); }

#endif
