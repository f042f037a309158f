#include "pair_set.h"

#include <string.h>

#include "alloc.h"

static void insert(uint64_t *keys, uint32_t capacity, uint64_t key)
{
    uint32_t slot = bpx__pair_slot(key, capacity);
    while (keys[slot] != BPX_PAIR_SET_EMPTY)
        slot = (slot + 1) & (capacity - 1);
    keys[slot] = key;
}

bool bpx__pair_set_reserve(bpx_pair_set *s, uint32_t extra)
{
    uint64_t need = ((uint64_t)s->count + extra) * 2;
    if (need <= s->capacity)
        return true;
    uint64_t capacity = s->capacity ? s->capacity : 64;
    while (capacity < need)
        capacity *= 2;
    if (capacity > (1ull << 31))
        return false;
    uint64_t *keys = bpx__alloc(sizeof(uint64_t) * capacity);
    if (!keys)
        return false;
    memset(keys, 0xFF, sizeof(uint64_t) * capacity); // every slot BPX_PAIR_SET_EMPTY
    for (uint32_t k = 0; k < s->capacity; k++)
        if (s->keys[k] != BPX_PAIR_SET_EMPTY)
            insert(keys, (uint32_t)capacity, s->keys[k]);
    bpx__free(s->keys, sizeof(uint64_t) * s->capacity);
    s->keys = keys;
    s->capacity = (uint32_t)capacity;
    return true;
}

bool bpx__pair_set_add(bpx_pair_set *s, uint64_t key)
{
    if (bpx__pair_set_has(s, key))
        return false;
    insert(s->keys, s->capacity, key);
    s->count++;
    return true;
}

// Empties `slot` and moves later keys of its cluster back so that every key stays reachable
// from its home slot without passing a free one.
static void erase_at(bpx_pair_set *s, uint32_t slot)
{
    uint32_t mask = s->capacity - 1, hole = slot;
    for (uint32_t next = (hole + 1) & mask; s->keys[next] != BPX_PAIR_SET_EMPTY;
         next = (next + 1) & mask) {
        uint32_t home = bpx__pair_slot(s->keys[next], s->capacity);
        // The key at `next` may fill the hole when its home is not in (hole, next], cyclically.
        bool stays = hole <= next ? (hole < home && home <= next) : (hole < home || home <= next);
        if (!stays) {
            s->keys[hole] = s->keys[next];
            hole = next;
        }
    }
    s->keys[hole] = BPX_PAIR_SET_EMPTY;
    s->count--;
}

bool bpx__pair_set_remove(bpx_pair_set *s, uint64_t key)
{
    if (!s->count)
        return false;
    for (uint32_t slot = bpx__pair_slot(key, s->capacity);; slot = (slot + 1) & (s->capacity - 1)) {
        if (s->keys[slot] == key) {
            erase_at(s, slot);
            return true;
        }
        if (s->keys[slot] == BPX_PAIR_SET_EMPTY)
            return false;
    }
}

void bpx__pair_set_remove_if(bpx_pair_set *s, bool (*drop)(uint64_t key, const void *context),
                             const void *context)
{
    // An erase moves keys into the slot just emptied, which is looked at again; keys moved from
    // the front of the table to its end were looked at already and kept.
    for (uint32_t slot = 0; slot < s->capacity && s->count;) {
        if (s->keys[slot] != BPX_PAIR_SET_EMPTY && drop(s->keys[slot], context))
            erase_at(s, slot);
        else
            slot++;
    }
}

void bpx__pair_set_free(bpx_pair_set *s)
{
    bpx__free(s->keys, sizeof(uint64_t) * s->capacity);
    *s = (bpx_pair_set){0};
}
