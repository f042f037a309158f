// A complete bpx program: the paper's two-phase interface in a frame loop.
// Eight unit cubes on a line, spaced 1.5 apart, drift together; each frame prints its pairs.
#include <bpx/bpx.h>
#include <stdio.h>

int main(void)
{
    enum { N = 8 };
    float minima[N][3];  // initialisation: each object's box centred at the origin (its minima)
    float centres[N][3]; // updating: each object's current centre
    for (int i = 0; i < N; i++) {
        minima[i][0] = minima[i][1] = minima[i][2] = -0.5f; // a unit cube: maxima are +0.5
        centres[i][0] = 1.5f * (float)i;
        centres[i][1] = centres[i][2] = 0.0f;
    }

    bpx_world_def def = bpx_default_world_def(); // backend auto, one thread
    def.worker_count = 2;
    bpx_world *world;
    if (bpx_world_create(&def, &world) != BPX_OK)
        return 1;
    if (bpx_world_load_extents(world, &minima[0][0], N) != BPX_OK) {
        fprintf(stderr, "%s\n", bpx_world_error(world)->message);
        bpx_world_destroy(world);
        return 1;
    }

    for (int frame = 0; frame < 3; frame++) {
        for (int i = 0; i < N; i++)
            centres[i][0] *= 0.8f; // everything slides towards x = 0
        if (bpx_world_update_centres(world, &centres[0][0]) != BPX_OK ||
            bpx_world_collide(world) != BPX_OK) {
            fprintf(stderr, "%s\n", bpx_world_error(world)->message);
            bpx_world_destroy(world);
            return 1;
        }
        size_t count;
        const bpx_pair *pairs = bpx_world_pairs(world, &count);
        printf("frame %d: %zu pairs:", frame, count);
        for (size_t k = 0; k < count; k++)
            printf(" (%u,%u)", pairs[k].i, pairs[k].j);
        printf("\n");
    }
    bpx_world_destroy(world);
    return 0;
}
