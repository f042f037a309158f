// The CPU-IC interface of the model: SSRAM read pipeline, collision write port, link costs.
#include "hw/interface.h"

#include <string.h>

void bpx__hw_interface_reset(bpx_hw_interface *ifc, int latency, const bpx_model_link *link,
                             bpx_pair_list *collisions)
{
    memset(ifc->pipe, 0, sizeof ifc->pipe);
    ifc->head = 0;
    ifc->latency = latency;
    ifc->request = false;
    ifc->write = false;
    ifc->collisions = collisions;
    if (collisions)
        collisions->count = 0;
    ifc->out_of_memory = false;
    ifc->count_register = 0;
    ifc->link = *link;
    ifc->transfer_ns = 0;
    ifc->dma_transfers = 0;
    ifc->register_accesses = 0;
    ifc->bytes_to_board = 0;
    ifc->bytes_to_host = 0;
}

bool bpx__hw_interface_busy(const bpx_hw_interface *ifc)
{
    for (int k = 0; k < ifc->latency; k++)
        if (ifc->pipe[k].valid)
            return true;
    return false;
}

double bpx__hw_link_dma_ns(const bpx_model_link *link, uint64_t bytes)
{
    return link->setup_ns + (double)bytes / link->bytes_per_s * 1e9;
}

void bpx__hw_link_dma(bpx_hw_interface *ifc, uint64_t bytes, bool to_board)
{
    ifc->transfer_ns += bpx__hw_link_dma_ns(&ifc->link, bytes);
    ifc->dma_transfers++;
    if (to_board)
        ifc->bytes_to_board += bytes;
    else
        ifc->bytes_to_host += bytes;
}

void bpx__hw_link_register(bpx_hw_interface *ifc)
{
    ifc->transfer_ns += ifc->link.register_ns;
    ifc->register_accesses++;
}

void bpx__hw_host_sort(const bpx_pair *in, size_t count, uint32_t n, size_t *counts, bpx_pair *tmp,
                       bpx_pair *out)
{
    if (count == 0)
        return;
    // Pass 1, stable by j: in -> tmp. Pass 2, stable by i: tmp -> out. in is fully read before
    // out is written, so they may be the same array.
    memset(counts, 0, sizeof(size_t) * ((size_t)n + 1));
    for (size_t k = 0; k < count; k++)
        counts[in[k].j + 1]++;
    for (uint32_t v = 0; v < n; v++)
        counts[v + 1] += counts[v];
    for (size_t k = 0; k < count; k++)
        tmp[counts[in[k].j]++] = in[k];

    memset(counts, 0, sizeof(size_t) * ((size_t)n + 1));
    for (size_t k = 0; k < count; k++)
        counts[tmp[k].i + 1]++;
    for (uint32_t v = 0; v < n; v++)
        counts[v + 1] += counts[v];
    for (size_t k = 0; k < count; k++)
        out[counts[tmp[k].i]++] = tmp[k];
}
