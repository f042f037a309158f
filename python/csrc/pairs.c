// bpx for Python: what returns pairs (find_pairs and World.collide through collide_to_bytes,
// World.pairs, World.events) and the one limit on their size. SPDX-License-Identifier: MIT
#include "_bpx.h"

#include <stdio.h>
#include <string.h>

// The most pairs one result may hold: the bytearray that NumPy wraps holds at most
// PY_SSIZE_T_MAX bytes, 8 to a pair. On a 64-bit host no cycle reaches it (BPX_MAX_BOXES = 2^30
// boxes make fewer than 2^59 pairs, 2^62 bytes); on a 32-bit one 2^28 pairs do. The tests lower
// it (_set_max_pairs) to see the error without the memory.
static size_t max_pairs = (size_t)PY_SSIZE_T_MAX / sizeof(bpx_pair);

// A new bytearray for count pairs, or TooManyPairsError (BPX_ERR_TOO_MANY_PAIRS) when count is
// past max_pairs: raised as soon as the count is known, before anything of its size is
// allocated or copied, where the allocation would otherwise fail as MemoryError (or the byte
// count overflow).
static PyObject *new_pairs(const char *where, size_t count, char **data)
{
    if (count > max_pairs) {
        char message[160];
        snprintf(message, sizeof message,
                 "%zu pairs: more than the %zu one array of pairs can hold", count, max_pairs);
        return raise_status(where, BPX_ERR_TOO_MANY_PAIRS, message);
    }
    return new_bytes(count * sizeof(bpx_pair), data);
}

// Runs a cycle and returns its pairs as a new bytearray: the comparator first, without a
// buffer, to learn the count; then the emitter merges the blocks straight into the bytearray,
// the one copy of the pairs that the C call bpx_world_collide makes too. Called with the
// world's lock held and the GIL held; releases the GIL around bpx's work. A count past
// max_pairs raises TooManyPairsError before the merge (the cycle itself is done).
PyObject *collide_to_bytes(const char *where, bpx_world *world)
{
    size_t count = 0;
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = bpx_world_collide_into(world, NULL, 0, &count);
    Py_END_ALLOW_THREADS
    if (status != BPX_OK && status != BPX_ERR_CAPACITY)
        return raise_error(where, bpx_world_error(world));
    char *data = NULL;
    PyObject *out = new_pairs(where, count, &data);
    if (!out || count == 0)
        return out;
    size_t copied = 0;
    Py_BEGIN_ALLOW_THREADS
    status = bpx_world_copy_pairs(world, (bpx_pair *)data, count, &copied);
    Py_END_ALLOW_THREADS
    if (status != BPX_OK || copied != count) {
        Py_DECREF(out);
        return raise_status(where, status, "the pairs could not be read back");
    }
    return out;
}

PyObject *World_collide(WorldObject *self, PyObject *unused)
{
    (void)unused;
    static const char where[] = "World.collide";
    if (world_enter(self, where) != 0)
        return NULL;
    PyObject *out = collide_to_bytes(where, self->world);
    world_leave(self);
    if (self->filter_error[0]) { // the filter raised: the cycle is done, its exception goes up
        Py_XDECREF(out);
        PyErr_Restore(self->filter_error[0], self->filter_error[1], self->filter_error[2]);
        self->filter_error[0] = self->filter_error[1] = self->filter_error[2] = NULL;
        return NULL;
    }
    return out;
}

static PyObject *pairs_to_bytes(const char *where, const bpx_pair *pairs, size_t count)
{
    char *data = NULL;
    PyObject *out = new_pairs(where, count, &data);
    if (out && count)
        memcpy(data, pairs, count * sizeof(bpx_pair));
    return out;
}

PyObject *World_pairs(WorldObject *self, PyObject *unused)
{
    (void)unused;
    static const char where[] = "World.pairs";
    if (world_enter(self, where) != 0)
        return NULL;
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(self->world, &count);
    PyObject *out;
    if (!pairs && bpx_world_error(self->world)->status == BPX_ERR_OUT_OF_MEMORY)
        out = raise_error(where, bpx_world_error(self->world));
    else
        out = pairs_to_bytes(where, pairs, count);
    world_leave(self);
    return out;
}

PyObject *World_events(WorldObject *self, PyObject *unused)
{
    (void)unused;
    static const char where[] = "World.events";
    if (world_enter(self, where) != 0)
        return NULL;
    bpx_pair_events events;
    PyObject *result = NULL;
    bpx_status status = bpx_world_pair_events(self->world, &events);
    if (status != BPX_OK) {
        // pair_events leaves the (const) world's error as it was: say here why there are none.
        raise_status(where, status,
                     status == BPX_ERR_BAD_STATE
                         ? "no events: the world was made without track_events, or its last "
                           "collide failed or has not run"
                         : bpx_status_string(status));
    } else {
        PyObject *began = pairs_to_bytes(where, events.began, events.began_count);
        PyObject *ended = began ? pairs_to_bytes(where, events.ended, events.ended_count) : NULL;
        if (began && ended)
            result = PyTuple_Pack(2, began, ended);
        Py_XDECREF(began);
        Py_XDECREF(ended);
    }
    world_leave(self);
    return result;
}

// _set_max_pairs(count) -> the previous limit; 0 restores the real one. For the tests only.
PyObject *py_set_max_pairs(PyObject *module, PyObject *arg)
{
    (void)module;
    size_t count = PyLong_AsSize_t(arg);
    if (count == (size_t)-1 && PyErr_Occurred())
        return NULL;
    size_t previous = max_pairs;
    max_pairs = count ? count : (size_t)PY_SSIZE_T_MAX / sizeof(bpx_pair);
    return PyLong_FromSize_t(previous);
}
