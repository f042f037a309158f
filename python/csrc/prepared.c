// bpx for Python: the queries of a prepared world (include/bpx/query.h, "Threads"):
// World.prepare_queries (bpx_world_prepare_queries), World.query_shared
// (bpx_world_query_shared: a reader, any number of threads at once, the GIL released) and
// World.query_each (bpx_world_query_each: a Python callable steers the walk hit by hit).
// SPDX-License-Identifier: MIT
#include "_bpx.h"

#include <math.h>

PyObject *World_prepare_queries(WorldObject *self, PyObject *unused)
{
    (void)unused;
    static const char where[] = "World.prepare_queries";
    if (world_enter(self, where) != 0)
        return NULL;
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = bpx_world_prepare_queries(self->world);
    Py_END_ALLOW_THREADS
    PyObject *result = NULL;
    if (status == BPX_OK) {
        Py_INCREF(Py_None);
        result = Py_None;
    } else if (bpx_world_error(self->world)->status == status)
        raise_error(where, bpx_world_error(self->world));
    else
        raise_status(where, status, bpx_status_string(status));
    world_leave(self);
    return result;
}

// query_shared(kind, closest, any, params, category, mask) -> (ids, fractions or None), as
// World.query's single query. Runs as one of the world's readers (access.c): with the GIL
// released, beside the other threads' shared queries, into a buffer of its own (on the stack
// for up to 64 hits; bpx says how many when they are more, and the query runs again).
PyObject *World_query_shared(WorldObject *self, PyObject *args)
{
    int kind, closest, any;
    PyObject *params, *category, *mask;
    if (!PyArg_ParseTuple(args, "ippOOO", &kind, &closest, &any, &params, &category, &mask))
        return NULL;
    const char *where = query_name(kind, 0);
    bpx_query query;
    if (one_query(where, kind, closest, any, params, category, mask, &query) != 0 ||
        reader_enter(self, where) != 0)
        return NULL;
    bpx_hit local[64];
    bpx_hit *hits = local;
    size_t capacity = sizeof local / sizeof local[0], count = 0;
    bpx_error err = {0};
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = bpx_world_query_shared(self->world, &query, hits, capacity, &count, &err);
    while (status == BPX_ERR_CAPACITY) {
        if (hits != local)
            PyMem_RawFree(hits);
        capacity = count;
        hits = count <= SIZE_MAX / sizeof *hits ? PyMem_RawMalloc(count * sizeof *hits) : NULL;
        if (!hits) {
            status = BPX_ERR_OUT_OF_MEMORY;
            break;
        }
        status = bpx_world_query_shared(self->world, &query, hits, capacity, &count, &err);
    }
    Py_END_ALLOW_THREADS
    reader_leave(self);
    PyObject *result = NULL;
    if (status == BPX_OK)
        result = hits_result(hits, count, kind);
    else if (status == BPX_ERR_OUT_OF_MEMORY && err.status != status)
        PyErr_NoMemory();
    else
        raise_query_error(where, &err, 0);
    if (hits && hits != local)
        PyMem_RawFree(hits);
    return result;
}

typedef struct each_context {
    WorldObject *self;
    PyObject *fn;
    PyObject *error[3]; // what fn raised (PyErr_Fetch's type, value, traceback)
} each_context;

// bpx_query_hit_fn for a Python callable fn(id, fraction, user_data) -> None or a number. The
// query runs without the GIL, so it is taken back for each call. None goes on (+infinity), a
// number steers as bpx's callback does; an exception stops the walk (0) and query_each raises it.
static float call_hit_fn(const bpx_hit *hit, uint64_t user_data, void *context)
{
    each_context *c = context;
    PyGILState_STATE gil = PyGILState_Ensure();
    float steer = 0.0f;
    if (!c->error[0]) {
        callback_frame frame;
        callback_begin(&frame, c->self);
        PyObject *answer = PyObject_CallFunction(c->fn, "IdK", hit->id, (double)hit->fraction,
                                                 (unsigned long long)user_data);
        callback_end(&frame);
        double value = answer == Py_None ? INFINITY : answer ? PyFloat_AsDouble(answer) : -1.0;
        Py_XDECREF(answer);
        if (PyErr_Occurred())
            PyErr_Fetch(&c->error[0], &c->error[1], &c->error[2]);
        else
            steer = (float)value;
    }
    PyGILState_Release(gil);
    return steer;
}

// query_each(kind, params, category, mask, fn, shared) -> None. shared: as one of the world's
// readers, on a world prepared before (StateError if it was not, or changed since); else with
// the world's lock held, preparing it first (as any query brings the tree up to date).
PyObject *World_query_each(WorldObject *self, PyObject *args)
{
    int kind, shared;
    PyObject *params, *category, *mask, *fn;
    if (!PyArg_ParseTuple(args, "iOOOOp", &kind, &params, &category, &mask, &fn, &shared))
        return NULL;
    const char *where = query_name(kind, 0);
    if (!PyCallable_Check(fn))
        return raise_status(where, BPX_ERR_INVALID_ARGUMENT, "each must be callable");
    bpx_query query;
    if (one_query(where, kind, 0, 0, params, category, mask, &query) != 0)
        return NULL;
    if ((shared ? reader_enter(self, where) : world_enter(self, where)) != 0)
        return NULL;
    each_context context = {self, fn, {NULL, NULL, NULL}};
    bpx_error err = {0};
    bpx_status status = BPX_OK;
    Py_BEGIN_ALLOW_THREADS
    if (!shared)
        status = bpx_world_prepare_queries(self->world);
    if (status == BPX_OK)
        status = bpx_world_query_each(self->world, &query, call_hit_fn, &context, &err);
    else
        err = *bpx_world_error(self->world);
    Py_END_ALLOW_THREADS
    if (shared)
        reader_leave(self);
    else
        world_leave(self);
    if (context.error[0]) {
        PyErr_Restore(context.error[0], context.error[1], context.error[2]);
        return NULL;
    }
    if (status != BPX_OK)
        return raise_query_error(where, &err, 0);
    Py_RETURN_NONE;
}
