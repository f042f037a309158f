// bpx for Python: what returns pairs (find_pairs and World.collide through collide_to_bytes,
// World.pairs, World.events) and the one limit on their size. SPDX-License-Identifier: MIT
#include "_bpx.h"

#include <stdio.h>
#include <string.h>
#include <time.h>

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

// ---------------------------------------------------------------------------------------------
// One-shot

const char find_pairs_doc[] =
    "find_pairs(boxes, backend, threads) -> bytearray\n\n"
    "Pairs of a C-contiguous float32 buffer of 6 floats per box, as 2 uint32 per pair.";

PyObject *py_find_pairs(PyObject *module, PyObject *args)
{
    (void)module;
    static const char where[] = "find_pairs";
    PyObject *obj;
    const char *backend_name;
    int threads;
    if (!PyArg_ParseTuple(args, "Osi", &obj, &backend_name, &threads))
        return NULL;
    bpx_world_def def = bpx_default_world_def();
    if (backend_from_name(where, backend_name, &def.backend) != 0)
        return NULL;
    Py_buffer view;
    uint32_t n;
    if (get_rows(where, obj, 'f', 6, &view, &n) != 0)
        return NULL;
    last_input_address = (uintptr_t)view.buf;
    def.worker_count = threads;
    def.capacity_hint = n;
    bpx_world *world = NULL;
    bpx_error err = {0};
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = create_world(&def, &world, &err);
    if (status == BPX_OK) {
        status = bpx_world_set_boxes(world, (const bpx_box *)view.buf, n);
        if (status != BPX_OK)
            err = *bpx_world_error(world);
    }
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view); // the world holds its own copy of the boxes from here
    PyObject *out = status == BPX_OK ? collide_to_bytes(where, world) : raise_error(where, &err);
    Py_BEGIN_ALLOW_THREADS
    bpx_world_destroy(world);
    Py_END_ALLOW_THREADS
    return out;
}

// The C timing the benchmark sets Python's overhead against: the fastest of `repeats` calls of
// bpx_find_pairs (one thread) on the same memory, into a buffer already big enough, in ns.
PyObject *py_time_c_find_pairs(PyObject *module, PyObject *args)
{
    (void)module;
    static const char where[] = "_time_c_find_pairs";
    PyObject *obj;
    const char *backend_name;
    int repeats;
    if (!PyArg_ParseTuple(args, "Osi", &obj, &backend_name, &repeats))
        return NULL;
    bpx_backend backend;
    if (backend_from_name(where, backend_name, &backend) != 0)
        return NULL;
    Py_buffer view;
    uint32_t n;
    if (get_rows(where, obj, 'f', 6, &view, &n) != 0)
        return NULL;
    size_t count = 0;
    bpx_error err;
    bpx_status status = bpx_find_pairs(view.buf, n, backend, NULL, 0, &count, &err);
    if (status != BPX_OK && status != BPX_ERR_CAPACITY) {
        PyBuffer_Release(&view);
        return raise_error(where, &err);
    }
    bpx_pair *out = PyMem_RawMalloc(count ? count * sizeof(bpx_pair) : 1);
    if (!out) {
        PyBuffer_Release(&view);
        return PyErr_NoMemory();
    }
    uint64_t best = UINT64_MAX;
    Py_BEGIN_ALLOW_THREADS
    for (int r = 0; r < repeats && status != BPX_ERR_OUT_OF_MEMORY; r++) {
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        status = bpx_find_pairs(view.buf, n, backend, out, count, &count, &err);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        uint64_t ns = (uint64_t)(t1.tv_sec - t0.tv_sec) * 1000000000u +
                      (uint64_t)(t1.tv_nsec - t0.tv_nsec);
        if (ns < best)
            best = ns;
    }
    Py_END_ALLOW_THREADS
    PyMem_RawFree(out);
    PyBuffer_Release(&view);
    if (status != BPX_OK)
        return raise_error(where, &err);
    return PyLong_FromUnsignedLongLong(best);
}
