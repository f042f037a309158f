// Queries in a frame loop: a mouse pick (the closest box a ray hits) and a trigger region
// (every box inside it), on a world whose boxes move each frame.
// Twelve crates stand in a row along x; a ray from the camera picks the nearest one, and a
// trigger volume around x = 6 reports who is inside as the crates slide past.
#include <bpx/bpx.h>
#include <stdio.h>

int main(void)
{
    enum { N = 12 };
    bpx_box crates[N];
    bpx_world *world;
    bpx_world_def def = bpx_default_world_def();
    if (bpx_world_create(&def, &world) != BPX_OK)
        return 1;
    const float eye[3] = {-5.0f, 0.5f, 0.5f}, forward[3] = {1.0f, 0.0f, 0.0f};
    bpx_query pick = bpx_query_ray(eye, forward, 100.0f, true); // closest hit within 100
    bpx_query trigger = bpx_query_box((bpx_box){{5.5f, 0.0f, 0.0f}, {6.5f, 1.0f, 1.0f}});
    for (int frame = 0; frame < 3; frame++) {
        for (int i = 0; i < N; i++) { // crate i slides along x by one unit a frame
            float x = 2.0f * (float)i - (float)frame;
            crates[i] = (bpx_box){{x, 0.0f, 0.0f}, {x + 1.0f, 1.0f, 1.0f}};
        }
        if (bpx_world_set_boxes(world, crates, N) != BPX_OK)
            break;
        bpx_hit hit, inside[N];
        size_t count = 0;
        if (bpx_world_query(world, &pick, &hit, 1, &count) != BPX_OK) // the tree builds here
            break;
        if (count)
            printf("frame %d: the ray picks crate %u at distance %g\n", frame, hit.id,
                   (double)hit.fraction);
        if (bpx_world_query(world, &trigger, inside, N, &count) != BPX_OK)
            break;
        printf("frame %d: %zu in the trigger:", frame, count);
        for (size_t k = 0; k < count; k++)
            printf(" %u", inside[k].id);
        printf("\n");
    }
    const bpx_error *error = bpx_world_error(world); // valid until the world is destroyed
    bpx_status status = error->status;
    if (status != BPX_OK)
        fprintf(stderr, "%s\n", error->message);
    bpx_world_destroy(world);
    return status == BPX_OK ? 0 : 1;
}
