// bpx demo's totals over a run and its report: the tables on stdout, or JSON (stdout and
// stats.json). SPDX-License-Identifier: MIT

#include <math.h>
#include <string.h>

#include "bpx_trace.h"
#include "demo_cmd.h"
#include "demo_png.h"

static double momentum_drift(const demo_totals *t)
{
    double sum = 0;
    for (int a = 0; a < 3; a++) {
        double d = t->momentum_end[a] - t->momentum_start[a] - t->wall_impulse[a];
        sum += d * d;
    }
    return sqrt(sum);
}

static void momentum_scale_of(const demo_sim *sim, demo_totals *t)
{
    // The sum of |m v_i|: the size momentum rounding is relative to.
    const double *v = demo_sim_velocities(sim);
    double sum = 0;
    for (uint32_t i = 0; i < demo_sim_count(sim); i++)
        sum +=
            sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
    t->momentum_scale = sum * demo_sim_params(sim)->mass;
}

void demo_cmd_finish_totals(const demo_sim *sim, demo_totals *t)
{
    t->energy_end = demo_sim_kinetic_energy(sim);
    demo_sim_momentum(sim, t->momentum_end);
    demo_sim_wall_impulse(sim, t->wall_impulse);
    t->max_penetration = demo_sim_max_penetration(sim);
    t->max_speed = demo_sim_max_speed(sim);
    const double *v = demo_sim_velocities(sim);
    size_t n3 = 3 * (size_t)demo_sim_count(sim), inside = 0;
    for (size_t k = 0; k < n3; k++)
        inside += fabs(v[k]) <= 15.0;
    t->within_15 = n3 ? (double)inside / (double)n3 : 0;
}

void demo_cmd_accumulate(demo_totals *t, const demo_step *s)
{
    t->cycles++;
    t->broad_ns += (double)s->broad_ns;
    t->narrow_ns += (double)s->narrow_ns;
    t->response_ns += (double)s->response_ns;
    t->physics_ns += (double)s->physics_ns;
    t->bpx_update_ns += (double)s->bpx.update_ns;
    t->bpx_compare_ns += (double)s->bpx.compare_ns;
    t->bpx_emit_ns += (double)s->bpx.emit_ns;
    t->pairs += (double)s->pairs;
    t->contacts += (double)s->contacts;
    t->impulses += (double)s->impulses;
    t->wall_hits += (double)s->wall_hits;
}

static const char *simd_label(const demo_sim *sim)
{
    return demo_sim_backend(sim) == BPX_BACKEND_BRUTE ? bpx_simd_name(demo_sim_simd(sim)) : "-";
}

void demo_cmd_print_json(FILE *f, const demo_options *o, const demo_sim *sim, const demo_totals *t,
                         const char *picture_dir)
{
    const demo_params *p = demo_sim_params(sim);
    fprintf(f,
            "{\n"
            "  \"spheres\": %u,\n"
            "  \"radius_m\": %.17g,\n"
            "  \"box_m\": [%.17g, %.17g, %.17g],\n"
            "  \"dt_s\": %.17g,\n"
            "  \"restitution\": %.17g,\n"
            "  \"mass_kg\": %.17g,\n"
            "  \"layers\": %u,\n"
            "  \"seed\": %llu,\n"
            "  \"backend\": \"%s\",\n"
            "  \"simd\": \"%s\",\n"
            "  \"threads\": %d,\n"
            "  \"cycles\": %llu,\n"
            "  \"simulated_s\": %.9g,\n"
            "  \"wall_s\": %.6g,\n",
            p->sphere_count, p->radius, t->box[0], t->box[1], t->box[2], p->dt, p->restitution,
            p->mass, p->layers, (unsigned long long)p->seed,
            bpx_backend_name(demo_sim_backend(sim)), simd_label(sim), o->threads,
            (unsigned long long)t->cycles, (double)t->cycles * p->dt, t->wall_s);
    fprintf(f,
            "  \"stage_ms_per_cycle\": {\"broad\": %.6g, \"narrow\": %.6g, \"response\": %.6g, "
            "\"physics\": %.6g, \"display\": %.6g},\n"
            "  \"broad_phase_ms_per_cycle\": %.6g,\n"
            "  \"bpx_ms_per_cycle\": {\"update\": %.6g, \"compare\": %.6g, \"emit\": %.6g},\n"
            "  \"pairs_per_cycle\": %.6g,\n"
            "  \"contacts_per_cycle\": %.6g,\n"
            "  \"impulses_per_cycle\": %.6g,\n"
            "  \"wall_hits_per_cycle\": %.6g,\n",
            per_cycle(t->broad_ns, t) * 1e-6, per_cycle(t->narrow_ns, t) * 1e-6,
            per_cycle(t->response_ns, t) * 1e-6, per_cycle(t->physics_ns, t) * 1e-6,
            per_cycle(t->display_ns, t) * 1e-6, per_cycle(t->broad_ns, t) * 1e-6,
            per_cycle(t->bpx_update_ns, t) * 1e-6, per_cycle(t->bpx_compare_ns, t) * 1e-6,
            per_cycle(t->bpx_emit_ns, t) * 1e-6, per_cycle(t->pairs, t), per_cycle(t->contacts, t),
            per_cycle(t->impulses, t), per_cycle(t->wall_hits, t));
    fprintf(f,
            "  \"kinetic_energy_J\": {\"start\": %.17g, \"end\": %.17g, \"drift_relative\": "
            "%.6g},\n"
            "  \"momentum_kg_m_s\": {\"start\": [%.17g, %.17g, %.17g], \"end\": [%.17g, %.17g, "
            "%.17g], \"wall_impulse\": [%.17g, %.17g, %.17g], \"drift\": %.6g, "
            "\"drift_relative\": %.6g},\n"
            "  \"max_penetration_m\": %.6g,\n"
            "  \"max_speed_m_s\": %.6g,\n"
            "  \"velocity_components_within_15_m_s\": %.6g,\n"
            "  \"pictures\": %d,\n"
            "  \"picture_dir\": ",
            t->energy_start, t->energy_end,
            t->energy_start > 0 ? (t->energy_end - t->energy_start) / t->energy_start : 0.0,
            t->momentum_start[0], t->momentum_start[1], t->momentum_start[2], t->momentum_end[0],
            t->momentum_end[1], t->momentum_end[2], t->wall_impulse[0], t->wall_impulse[1],
            t->wall_impulse[2], momentum_drift(t),
            t->momentum_scale > 0 ? momentum_drift(t) / t->momentum_scale : 0.0, t->max_penetration,
            t->max_speed, t->within_15, t->pictures);
    // Paths are printed as JSON strings; escape what JSON requires.
    const char *strings[2] = {picture_dir, o->record};
    for (int s = 0; s < 2; s++) {
        if (s == 1)
            fprintf(f, ",\n  \"trace\": ");
        if (!strings[s]) {
            fprintf(f, "null");
            continue;
        }
        fputc('"', f);
        for (const char *c = strings[s]; *c; c++) {
            if (*c == '"' || *c == '\\')
                fprintf(f, "\\%c", *c);
            else if ((unsigned char)*c < 0x20)
                fprintf(f, "\\u%04x", (unsigned char)*c);
            else
                fputc(*c, f);
        }
        fputc('"', f);
    }
    fprintf(f, "\n}\n");
}

void demo_cmd_print_tables(const demo_options *o, const demo_sim *sim, const demo_totals *t,
                           const char *picture_dir)
{
    const demo_params *p = demo_sim_params(sim);
    printf("bpx demo: %u spheres of radius %g m in a %g x %g x %g m box (W x H x D); %llu cycles "
           "of %.6g s (%.3g s simulated) in %.2f s\n",
           p->sphere_count, p->radius, t->box[0], t->box[1], t->box[2],
           (unsigned long long)t->cycles, p->dt, (double)t->cycles * p->dt, t->wall_s);
    printf("broad phase: bpx backend %s (simd %s), %d thread%s; restitution %g, mass %g kg, "
           "seed %llu\n\n",
           bpx_backend_name(demo_sim_backend(sim)), simd_label(sim), o->threads,
           o->threads == 1 ? "" : "s", p->restitution, p->mass, (unsigned long long)p->seed);
    double stages[5] = {t->broad_ns, t->narrow_ns, t->response_ns, t->physics_ns, t->display_ns};
    const char *names[5] = {"1. broad phase (bpx)", "2. narrow phase", "3. collision response",
                            "4. physics", "5. display"};
    double total = 0;
    for (int s = 0; s < 5; s++)
        total += stages[s];
    printf("| stage | mean ms per cycle | share |\n|---|---:|---:|\n");
    for (int s = 0; s < 5; s++)
        printf("| %s | %.4f | %.1f %% |\n", names[s], per_cycle(stages[s], t) * 1e-6,
               total > 0 ? 100.0 * stages[s] / total : 0.0);
    printf("| all five | %.4f | 100 %% |\n\n", per_cycle(total, t) * 1e-6);

    printf("| statistic | value |\n|---|---|\n");
    printf("| cycles | %llu |\n", (unsigned long long)t->cycles);
    printf("| mean broad-phase time per cycle | %.4f ms (bpx: updater %.4f, comparator %.4f, "
           "emitter %.4f) |\n",
           per_cycle(t->broad_ns, t) * 1e-6, per_cycle(t->bpx_update_ns, t) * 1e-6,
           per_cycle(t->bpx_compare_ns, t) * 1e-6, per_cycle(t->bpx_emit_ns, t) * 1e-6);
    printf("| mean overlapping AABB pairs per cycle (broad phase) | %.3f |\n",
           per_cycle(t->pairs, t));
    printf("| mean sphere contacts per cycle (narrow phase) | %.3f |\n", per_cycle(t->contacts, t));
    printf("| mean impulses per cycle | %.3f between spheres, %.3f at walls |\n",
           per_cycle(t->impulses, t), per_cycle(t->wall_hits, t));
    printf("| kinetic energy | %.6g J at the start, %.6g J at the end: drift %+.3g (relative) |\n",
           t->energy_start, t->energy_end,
           t->energy_start > 0 ? (t->energy_end - t->energy_start) / t->energy_start : 0.0);
    printf("| momentum drift, \\|p(end) - p(start) - wall impulses\\| | %.3g kg m/s (%.3g "
           "relative to the sum of \\|m v\\|) |\n",
           momentum_drift(t), t->momentum_scale > 0 ? momentum_drift(t) / t->momentum_scale : 0);
    printf("| largest sphere overlap, largest speed | %.3g m, %.4g m/s |\n", t->max_penetration,
           t->max_speed);
    printf("| velocity components within +-15 m/s at the end | %.1f %% |\n", 100.0 * t->within_15);
    if (picture_dir && demo_png_available())
        printf("| pictures | %d PNG files, %dx%d, in %s/ (and stats.json) |\n", t->pictures,
               t->width, t->height, picture_dir);
    else if (picture_dir)
        printf("| pictures | none: without libpng (stats.json is in %s/) |\n", picture_dir);
    if (o->record)
        printf("| trace | %s: %llu cycles of %u boxes, %llu bytes |\n", o->record,
               (unsigned long long)t->cycles, p->sphere_count,
               (unsigned long long)(BPX_TRACE_HEADER_BYTES +
                                    t->cycles * (uint64_t)p->sphere_count * BPX_TRACE_BOX_BYTES));
}

void demo_cmd_start_totals(const demo_sim *sim, demo_totals *t)
{
    memset(t, 0, sizeof *t);
    t->energy_start = demo_sim_kinetic_energy(sim);
    demo_sim_momentum(sim, t->momentum_start);
    momentum_scale_of(sim, t);
    demo_sim_box_size(sim, t->box);
}
