// Periodic worlds (bpx_world_def.period): the cycle's pairs over every periodic image, found by
// the image search of src/neighbors on the world's backend and workers.
#pragma once

#include "bpx/bpx.h"

/// What the image search keeps between the cycles of a periodic world, so that its steady
/// cycle allocates nothing: the world of images (its backend state, sap's sorted lists
/// included, carries over) and the search's per-object and per-image arrays.
typedef struct bpx__search_keep {
    bpx_world *inner;
    bpx_box *boxes; // the boxes with their images, as the world of images gets them (AoS input)
    size_t box_capacity;
    int32_t (*wrap)[3]; // per object: its wrap
    size_t wrap_capacity;
    uint8_t *exact; // per object: whether its image is its box
    size_t exact_capacity;
    uint32_t *marked; // the objects that wrap or have ghosts
    uint32_t marked_capacity;
    // wrap is 0 and exact 1 at every object but moved_ids[0 .. moved_count), last cycle's
    // wrapped objects: the next cycle resets those few, not the whole arrays (false: it clears
    // them whole).
    bool clean;
    uint32_t moved_count;
    bpx_box *images; // the moved images and the ghosts
    size_t image_capacity;
    uint32_t *ghost_owner;
    size_t ghost_owner_capacity;
    int32_t (*ghost_shift)[3];
    size_t ghost_shift_capacity;
    uint32_t *moved_ids;
    size_t moved_capacity;
    bpx_box *moved_boxes; // the sparse path's: moved images apart from the ghosts (in images)
    size_t moved_box_capacity;
    void *imaged; // the pairs with an image (neighbors.c's found), before their sort
    size_t imaged_capacity;
} bpx__search_keep;

/// What a periodic world keeps between cycles: the image search's state, the live boxes handed
/// to it, and the image pairs of the last cycle.
typedef struct bpx_periodic {
    bpx__search_keep search;
    bpx_box *boxes;    // the live boxes, in id order
    uint32_t *ids;     // boxes[k]'s id, when some ids are removed
    uint32_t capacity; // of boxes and ids
    bpx_neighbor_list images; // sorted by (i, j, shift); filtered as the pairs are
} bpx_periodic;

struct bpx_world;

/// Whether the world has a periodic axis.
bool bpx__world_periodic(const struct bpx_world *w);
/// Checks a period as bpx_world_create does; names the axis in err.
bpx_status bpx__period_check(const double period[3], bpx_error *err);
/// The comparator of a periodic world: the image pairs into w->periodic.images, the distinct
/// (i, j) pairs (i < j) into one block of the emitter, for the world's filters to follow.
bpx_status bpx__periodic_compare(struct bpx_world *w);
/// After the filters: keeps the image pairs of the pairs that passed them (a box and its own
/// image: when the box would pair with a box of its own filter and group).
void bpx__periodic_filter_images(struct bpx_world *w);
/// The backend the last periodic cycle ran (auto's choice), or BPX_BACKEND_COUNT before one.
bpx_backend bpx__periodic_backend(const struct bpx_world *w);
void bpx__periodic_free(bpx_periodic *p);

/// The world of images' boxes: n boxes copied from soa (a bpx__soa_boxes, search.h), moved[m]
/// put at moved_ids[m], then extra_count boxes after them; ids 0 .. n + extra_count - 1, all
/// live. The boxes are finite with min <= max already: no check. world.c.
/// A periodic world's own float32 boxes, read in place (structure of arrays): an input format
/// of the world's search only (bpx__find_neighbors_kept), never bpx_find_neighbors'.
#define BPX__BOXES_SOA ((bpx_input_format)100)

typedef struct bpx__soa_boxes {
    const float *lo[3];
    const float *hi[3];
    // The set_boxes that wrote them found, or NULL: the least lo per axis, and the largest
    // |coordinate| (the image search's cell origin and magnitude, without a pass of its own;
    // it checks them as it reads the boxes).
    const float *low;
    float most;
} bpx__soa_boxes;
bpx_status bpx__world_set_images(bpx_world *w, const bpx__soa_boxes *soa, uint32_t n,
                                 const uint32_t *moved_ids, const bpx_box *moved,
                                 uint32_t moved_count, const bpx_box *extra, uint32_t extra_count);

/// Float64 boxes rounded outward to float32 (no pair is lost), into SoA arrays. neighbors.c.
void bpx__round_boxes64_soa(const bpx_box64 *in, uint32_t n, float *const lo[3],
                            float *const hi[3]);

/// bpx_find_neighbors on float32 boxes (def->format BPX_BOXES_F32, BPX__BOXES_SOA) or float64
/// ones, on the world of images keep->inner (made with inner_def at the first call and kept)
/// and keep's arrays, into list (emptied; its arrays kept). neighbors.c.
bpx_status bpx__find_neighbors_kept(const bpx_neighbor_def *def, const void *boxes, uint32_t n,
                                    bpx__search_keep *keep, const bpx_world_def *inner_def,
                                    bpx_neighbor_list *list, bpx_error *err);
/// Frees what keep holds. neighbors.c.
void bpx__search_keep_free(bpx__search_keep *keep);
