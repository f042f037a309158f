// The model's CPU-IC communication interface (paper §4.5, §4.5.1): the board's six SSRAM banks
// as the chip sees them (a pipelined read port for the updater, a write port for the emitter's
// collisions), the n and collision-count registers, and the host link's cost.
#pragma once

#include "bpx/model.h"
#include "core/backend.h"

enum {
    BPX_HW_BANKS = 6,       // independent SSRAM banks on the ADM-XRC-II
    BPX_HW_MAX_LATENCY = 8, // SSRAM read latency bound (config range)
};

/// One SSRAM read in flight: the six banks' words at one address.
typedef struct bpx_hw_read {
    bool valid;
    uint32_t address;
    float word[BPX_HW_BANKS];
} bpx_hw_read;

typedef struct bpx_hw_interface {
    /// What the chip reads: word `address` of bank b is bank[b][address]. The host fills these
    /// between runs (the model may point a bank at host memory it already holds in bank layout;
    /// the DMA that would have copied it is still charged to the link).
    const float *bank[BPX_HW_BANKS];
    int latency; // clocks from read address to data

    /// Reads in flight, a ring: pipe[head] was issued last clock, pipe[(head + 1) % latency]
    /// latency clocks ago (what the updater sees now).
    bpx_hw_read pipe[BPX_HW_MAX_LATENCY];
    int head;
    // Inputs latched during evaluate, applied by commit.
    bool request; // the updater asks for `request_address` this clock
    uint32_t request_address;
    unsigned request_banks; // bit b: bank b is read
    bool write;             // the emitter's output register holds a collision
    bpx_pair write_pair;

    /// The collision RAM: one collision per address, in the order they were written.
    bpx_pair_list *collisions;
    bool out_of_memory; // the collision list could not grow (the run fails)

    // Registers.
    uint32_t n_register;
    uint64_t count_register;

    // Host link accounting for the current run.
    bpx_model_link link;
    double transfer_ns;
    uint64_t dma_transfers;
    uint64_t register_accesses;
    uint64_t bytes_to_board;
    uint64_t bytes_to_host;
} bpx_hw_interface;

/// Empties the read pipeline and the link counters; collisions go to `collisions` (cleared).
void bpx__hw_interface_reset(bpx_hw_interface *ifc, int latency, const bpx_model_link *link,
                             bpx_pair_list *collisions);

/// The updater's read request for this clock (called from its evaluate step).
static inline void bpx__hw_interface_request(bpx_hw_interface *ifc, uint32_t address,
                                             unsigned banks)
{
    ifc->request = true;
    ifc->request_address = address;
    ifc->request_banks = banks;
}

/// The read data arriving this clock (committed state).
static inline const bpx_hw_read *bpx__hw_interface_data(const bpx_hw_interface *ifc)
{
    int oldest = ifc->head + 1 == ifc->latency ? 0 : ifc->head + 1;
    return &ifc->pipe[oldest];
}

/// Evaluate: latch the emitter's output register (valid, pair) as this clock's bank write.
static inline void bpx__hw_interface_evaluate(bpx_hw_interface *ifc, bool out_valid, bpx_pair out)
{
    ifc->write = out_valid;
    ifc->write_pair = out;
}

/// Commit: the read pipeline advances (a requested address is read now) and a latched
/// collision is written at the next address. Returns false when the collision list cannot grow.
static inline bool bpx__hw_interface_commit(bpx_hw_interface *ifc)
{
    // Reads: the pipeline advances by one; a new request reads its banks at this edge, into
    // the slot of the oldest read (which the updater took this clock).
    if (++ifc->head == ifc->latency)
        ifc->head = 0;
    bpx_hw_read *slot = &ifc->pipe[ifc->head];
    slot->valid = ifc->request;
    if (ifc->request) {
        slot->address = ifc->request_address;
        for (int b = 0; b < BPX_HW_BANKS; b++)
            slot->word[b] =
                (ifc->request_banks >> b & 1u) ? ifc->bank[b][ifc->request_address] : 0.0f;
    }
    ifc->request = false;

    // Writes: one collision per address, at the address the count register points to.
    if (ifc->write) {
        bpx_pair_list *list = ifc->collisions;
        if (!bpx__list_reserve(list, 1)) { // geometric growth: rare, never per clock
            ifc->out_of_memory = true;
            return false;
        }
        list->pairs[list->count++] = ifc->write_pair;
        ifc->count_register = list->count;
        ifc->write = false;
    }
    return true;
}

/// Reads in flight.
bool bpx__hw_interface_busy(const bpx_hw_interface *ifc);

/// Host side: one DMA transfer of `bytes` (to the board or back).
void bpx__hw_link_dma(bpx_hw_interface *ifc, uint64_t bytes, bool to_board);
/// Host side: one register read or write.
void bpx__hw_link_register(bpx_hw_interface *ifc);
/// Time of one DMA transfer of `bytes` on this link, ns.
double bpx__hw_link_dma_ns(const bpx_model_link *link, uint64_t bytes);

/// Host side, after reading the collision RAM: sorts `count` pairs (indices < n) by (i, j) into
/// out with two stable counting passes (by j, then by i). counts holds n + 1 entries; tmp and
/// out hold count pairs each; in may alias out.
void bpx__hw_host_sort(const bpx_pair *in, size_t count, uint32_t n, size_t *counts, bpx_pair *tmp,
                       bpx_pair *out);
