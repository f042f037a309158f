// bpx model's reports: per-cycle sums, their means, the configuration, and per-clock lines.
// SPDX-License-Identifier: MIT

#include "model_cmd.h"

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// Reports

void model_report_add(report_sum *s, const bpx_model_report *r)
{
    s->cycles++;
    s->collisions += (double)r->collisions;
    s->update += (double)r->update_clocks;
    s->compare += (double)r->compare_clocks;
    s->stall += (double)r->stall_clocks;
    s->emit += (double)r->emit_clocks;
    s->chip += (double)r->chip_clocks;
    s->transfer_clocks += (double)r->transfer_clocks;
    s->chip_ns += r->chip_ns;
    s->transfer_ns += r->transfer_ns;
    s->cycle_ns += r->cycle_ns;
    s->dma += (double)r->dma_transfers;
    s->registers += (double)r->register_accesses;
    s->bytes_down += (double)r->bytes_to_board;
    s->bytes_up += (double)r->bytes_to_host;
    s->unit_tests += (double)r->unit_tests;
    s->discarded += (double)r->discarded_tests;
    s->achieved += r->achieved_read_bytes_per_s;
    s->fifo_peak = r->fifo_peak > s->fifo_peak ? r->fifo_peak : s->fifo_peak;
    s->last = *r;
}

static const double gib = 1024.0 * 1024.0 * 1024.0;

void model_print_report(const report_sum *s, const bpx_model_config *c)
{
    const bpx_model_report *r = &s->last;
    double cycle = mean(s, s->cycle_ns);
    printf("per cycle (mean of %d)   clocks        us   of the cycle\n", s->cycles);
    const struct {
        const char *name;
        double clocks, ns;
    } rows[] = {
        {"update", mean(s, s->update), mean(s, s->update) / c->clock_hz * 1e9},
        {"compare", mean(s, s->compare), mean(s, s->compare) / c->clock_hz * 1e9},
        {"  of which stalled", mean(s, s->stall), mean(s, s->stall) / c->clock_hz * 1e9},
        {"emit (after compare)", mean(s, s->emit), mean(s, s->emit) / c->clock_hz * 1e9},
        {"chip", mean(s, s->chip), mean(s, s->chip_ns)},
        {"transfer (link)", mean(s, s->transfer_clocks), mean(s, s->transfer_ns)},
    };
    for (size_t k = 0; k < sizeof rows / sizeof rows[0]; k++)
        printf("  %-20s %10.1f %10.2f   %5.1f %%\n", rows[k].name, rows[k].clocks,
               rows[k].ns * 1e-3, cycle > 0 ? 100 * rows[k].ns / cycle : 0);
    printf("  %-20s %10s %10.2f   predicted at %.1f MHz; communication share %.1f %%\n", "cycle",
           "", cycle * 1e-3, c->clock_hz * 1e-6,
           cycle > 0 ? 100 * mean(s, s->transfer_ns) / cycle : 0);
    printf("collisions per cycle: %.2f (emitter: %d FIFOs of %u entries, fullest %u)\n",
           mean(s, s->collisions), 4 * c->m - 2, c->fifo_depth, s->fifo_peak);
    printf("comparator: %.0f unit tests per cycle, %.1f %% discarded; peak read bandwidth %.3f "
           "GiB/s per 2m-width memory (%.3f GiB/s for all six), achieved %.3f GiB/s\n",
           mean(s, s->unit_tests), s->unit_tests > 0 ? 100 * s->discarded / s->unit_tests : 0,
           r->peak_read_bytes_per_s / gib, 6 * r->peak_read_bytes_per_s / gib,
           mean(s, s->achieved) / gib);
    printf("link: %.2f DMA transfers (%.0f bytes to the board, %.0f back) and %.0f register "
           "accesses per cycle\n",
           mean(s, s->dma), mean(s, s->bytes_down), mean(s, s->bytes_up), mean(s, s->registers));
    printf("boxes: %s (%u tile%s of %u)\n", r->on_chip ? "all on chip" : "tiled", r->tiles,
           r->tiles == 1 ? "" : "s", r->on_chip ? r->n : c->ram_depth / 2);
    printf("on-chip memory: comparator 6 x %d x %u words, updater 3 x %u words, FIFOs %d x %u "
           "entries: %.1f KiB in %d block RAMs of 18 Kb (%.1f %% of the XC2V6000's 144; the "
           "paper: 28 %% at m = 4, 56 %% at m = 8)\n",
           c->m, c->ram_depth, c->ram_depth, 4 * c->m - 2, c->fifo_depth,
           (double)r->on_chip_bytes / 1024, r->block_rams, 100.0 * r->block_rams / 144);
    if (r->collision_overflow)
        printf("note: more collisions than one SSRAM bank holds (%u words)\n", c->ssram_depth);
}

void model_print_config(const bpx_model_config *c)
{
    printf("model: m = %d (%d ports, %d comparison units), %.1f MHz, on-chip RAMs of %u boxes, "
           "store %s, FIFOs of %u, SSRAM latency %d\n",
           c->m, 2 * c->m, 2 * c->m - 1, c->clock_hz * 1e-6, c->ram_depth,
           bpx_model_store_name(c->store), c->fifo_depth, c->ssram_latency);
    printf("link: %.1f MB/s, %.1f us per DMA transfer, %.2f us per register access\n",
           c->link.bytes_per_s * 1e-6, c->link.setup_ns * 1e-3, c->link.register_ns * 1e-3);
}

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// Per-clock printing (--clocks)

void model_print_clock(const bpx_model_clock *c, void *user)
{
    clock_printer *p = user;
    if (p->left <= 0)
        return;
    p->left--;
    static const char *const phases[BPX_MODEL_PHASE_COUNT] = {"init", "update", "compare", "drain",
                                                              "wait"};
    printf("%8llu %-7s", (unsigned long long)c->clock, phases[c->phase]);
    if (c->addressing) {
        printf(" ports %u |", c->ports[0]);
        for (int k = 1; k < c->port_count; k++)
            if (c->ports[k] == BPX_MODEL_DISCARDED)
                printf(" -");
            else
                printf(" %u", c->ports[k]);
    }
    if (c->hits)
        printf("  hits 0x%llx (row %u)", (unsigned long long)c->hits, c->hit_row);
    if (c->stalled)
        printf("  STALL");
    if (c->emitted)
        printf("  out (%u, %u)", c->pair.i, c->pair.j);
    printf("  fifo %u\n", c->fifo_fill_max);
}
