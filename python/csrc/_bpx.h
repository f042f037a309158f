// bpx for Python: what the extension module's C files share. SPDX-License-Identifier: MIT
//
// _bpx.c holds the errors, the buffers, the World type and the module; pairs.c what returns
// pairs; query.c the query methods of World and the QUERY_* constants. Everything here has
// hidden visibility (the module exports PyInit__bpx alone).
#pragma once

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <pythread.h>

#include <bpx/bpx.h>

/// A bpx_world and the lock that lets one thread at a time use it.
typedef struct {
    PyObject_HEAD
    bpx_world *world;
    PyThread_type_lock lock;
    PyObject *pair_filter;  // the callable of set_pair_filter, or NULL
    unsigned long filter_thread; // the thread running the pair filter now, else 0
    PyObject *filter_error[3]; // an exception the filter raised in a collide (PyErr_Fetch's
                               // type, value, traceback), raised after it
} WorldObject;

// _bpx.c

/// Raises the bpx.Error subclass for err (where names the Python call); returns NULL.
PyObject *raise_error(const char *where, const bpx_error *err);
/// Raises an error that bpx itself did not report, as the bpx.Error subclass of status.
PyObject *raise_status(const char *where, bpx_status status, const char *message);
/// Borrows obj's memory as C-contiguous rows of items_per_row items ('f' float32, 'I' uint32,
/// 'i' int32, 'Q' uint64); on failure raises and returns -1 with nothing held.
int get_rows(const char *where, PyObject *obj, char kind, Py_ssize_t items_per_row, Py_buffer *view,
             uint32_t *rows);
/// A new uninitialised bytearray of size bytes; *data receives its memory.
PyObject *new_bytes(size_t size, char **data);
/// Takes the world's lock (StateError once closed); world_leave gives it back.
int world_enter(WorldObject *self, const char *where);
void world_leave(WorldObject *self);

// pairs.c

/// Runs a cycle into a new bytearray of pairs (the world's lock held; the GIL released around
/// bpx's work); TooManyPairsError when the count is past what one array can hold.
PyObject *collide_to_bytes(const char *where, bpx_world *world);
/// World.collide(), World.pairs(), World.events().
PyObject *World_collide(WorldObject *self, PyObject *unused);
PyObject *World_pairs(WorldObject *self, PyObject *unused);
PyObject *World_events(WorldObject *self, PyObject *unused);
/// _set_max_pairs(count) -> previous: lowers the pair limit for the tests (0: the real one).
PyObject *py_set_max_pairs(PyObject *module, PyObject *arg);

// query.c

/// World.query(kind, closest, any, params, categories, masks, batch) and World.query_stats().
PyObject *World_query(WorldObject *self, PyObject *args);
PyObject *World_query_stats(WorldObject *self, PyObject *unused);
/// Adds QUERY_BOX, QUERY_SPHERE, QUERY_RAY and QUERY_SWEEP to the module; -1 on failure.
int add_query_constants(PyObject *module);
