// libbpx_mpi's memory: the core's allocator (mpi_alloc.h).
#include "mpi_alloc.h"

#include <stdint.h>

#include "core/alloc.h"

void *bpx_mpi__alloc(size_t size)
{
    return bpx__alloc(size);
}

void bpx_mpi__free(void *memory, size_t size)
{
    bpx__free(memory, size);
}

int bpx_mpi__reserve(void **const arrays[], const size_t sizes[], int count, size_t *cap,
                     size_t need)
{
    enum { MOST = 16 };
    if (need <= *cap)
        return 0;
    if (count > MOST)
        return -1;
    size_t want = *cap + *cap / 2;
    if (want < need)
        want = need;
    void *grown[MOST];
    for (int k = 0; k < count; k++) {
        grown[k] = want <= SIZE_MAX / sizes[k] ? bpx_mpi__alloc(want * sizes[k]) : NULL;
        if (!grown[k]) {
            while (k-- > 0)
                bpx_mpi__free(grown[k], want * sizes[k]);
            return -1;
        }
    }
    for (int k = 0; k < count; k++) {
        bpx_mpi__free(*arrays[k], *cap * sizes[k]);
        *arrays[k] = grown[k];
    }
    *cap = want;
    return 0;
}

int bpx_mpi__grow(void **memory, size_t *cap, size_t need, size_t size)
{
    void **arrays[] = {memory};
    return bpx_mpi__reserve(arrays, &size, 1, cap, need);
}
