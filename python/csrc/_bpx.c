// bpx for Python: the extension module bpx._bpx. SPDX-License-Identifier: MIT
//
// A thin layer over the C API, written against the CPython C API and the buffer protocol only:
// it takes C-contiguous buffers of float32 or uint32 that the Python layer (bpx/_arrays.py) has
// already shaped and converted, hands their memory to bpx as it is (no copy), and returns
// results as bytearrays that NumPy wraps without a copy. It needs no NumPy headers to build.
//
// Every call that does real work runs with the GIL released. A world is used by one thread at
// a time (bpx.h), so each World holds a lock that its methods take; a second Python thread
// calling the same World waits for the first instead of racing it.
//
// The lock is in access.c, find_pairs and what returns pairs in pairs.c, the neighbour lists
// and periodic pairs in neighbors.c, the query methods of World in query.c and prepared.c;
// _bpx.h is what the files share.
#include "_bpx.h"

#include <stdio.h>
#include <string.h>
#include <time.h>

// bpx._errors._from_status(status_name, index, axis, message) -> the exception to raise, set at
// module initialisation so that every error path has it.
static PyObject *error_factory;

// Address of the last box, extent or centre buffer handed to bpx: the tests compare it with the
// NumPy array's own data pointer to check that nothing was copied on the way.
uintptr_t last_input_address;

// ---------------------------------------------------------------------------------------------
// Errors

// Raises the bpx.Error subclass for err's status, with err's message, box index and axis.
// where names the Python call ("World.set_boxes") so the message says what failed.
PyObject *raise_error(const char *where, const bpx_error *err)
{
    PyObject *index = err->index == UINT32_MAX ? Py_NewRef(Py_None)
                                               : PyLong_FromUnsignedLong(err->index);
    PyObject *axis = err->axis < 0 ? Py_NewRef(Py_None) : PyLong_FromLong(err->axis);
    const char *detail = err->message[0] ? err->message : bpx_status_string(err->status);
    PyObject *message = PyUnicode_FromFormat("%s: %s", where, detail);
    PyObject *exc = NULL;
    if (index && axis && message)
        exc = PyObject_CallFunction(error_factory, "sOOO", bpx_status_name(err->status), index,
                                    axis, message);
    Py_XDECREF(index);
    Py_XDECREF(axis);
    Py_XDECREF(message);
    if (exc) {
        PyErr_SetObject((PyObject *)Py_TYPE(exc), exc);
        Py_DECREF(exc);
    }
    return NULL;
}

// Raises an error that bpx itself did not report (a bad buffer, a closed world), as the
// bpx.Error subclass of status.
PyObject *raise_status(const char *where, bpx_status status, const char *message)
{
    bpx_error err = {.status = status, .index = UINT32_MAX, .axis = -1};
    snprintf(err.message, sizeof err.message, "%s", message);
    return raise_error(where, &err);
}

// ---------------------------------------------------------------------------------------------
// Buffers

// Borrows obj's memory as a C-contiguous array of items of the given kind ('f' float32, 'I'
// uint32, 'i' int32, 'Q' uint64), items_per_row to a row. The Python layer converts everything
// before it gets here; these checks keep a direct call with anything else from reading out of
// bounds.
int get_rows(const char *where, PyObject *obj, char kind, Py_ssize_t items_per_row, Py_buffer *view,
             uint32_t *rows)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) != 0)
        return -1;
    const char *format = view->format ? view->format : "B";
    if (format[0] == '<' || format[0] == '=' || format[0] == '@')
        format++; // native little-endian, which is all bpx's hosts are
    Py_ssize_t item_size = kind == 'Q' || kind == 'd' ? 8 : 4;
    const char *type_name = kind == 'f'   ? "float32"
                            : kind == 'd' ? "float64"
                            : kind == 'I' ? "uint32"
                            : kind == 'i' ? "int32"
                                          : "uint64";
    // NumPy writes uint64 as 'L' where unsigned long is 64 bits
    int format_ok = strlen(format) == 1 &&
                    (format[0] == kind || (kind == 'Q' && format[0] == 'L' && view->itemsize == 8));
    Py_ssize_t row_bytes = items_per_row * item_size;
    if (view->itemsize != item_size || !format_ok || view->len % row_bytes != 0) {
        char message[160];
        snprintf(message, sizeof message,
                 "expected a C-contiguous %s buffer of %zd items per row, got format '%s', "
                 "%zd bytes",
                 type_name, items_per_row, view->format, view->len);
        PyBuffer_Release(view);
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
        return -1;
    }
    Py_ssize_t count = view->len / row_bytes;
    if ((size_t)count > BPX_MAX_BOXES) {
        char message[96];
        snprintf(message, sizeof message, "%zd rows exceed BPX_MAX_BOXES (%u)", count,
                 BPX_MAX_BOXES);
        PyBuffer_Release(view);
        raise_status(where, BPX_ERR_TOO_MANY_BOXES, message);
        return -1;
    }
    *rows = (uint32_t)count;
    return 0;
}

// A bytearray of size bytes, uninitialised, for bpx to write into; NumPy wraps it as it is.
PyObject *new_bytes(size_t size, char **data)
{
    if (size > (size_t)PY_SSIZE_T_MAX)
        return PyErr_NoMemory();
    PyObject *out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)size);
    if (out)
        *data = PyByteArray_AS_STRING(out);
    return out;
}

int backend_from_name(const char *where, const char *name, bpx_backend *backend)
{
    if (bpx_backend_from_name(name, backend) == BPX_OK)
        return 0;
    char message[192];
    int used = snprintf(message, sizeof message, "no backend named '%s' (backends:", name);
    for (int b = 0; b < BPX_BACKEND_COUNT && used > 0 && (size_t)used < sizeof message; b++)
        used += snprintf(message + used, sizeof message - (size_t)used, "%s %s",
                         b ? "," : "", bpx_backend_name((bpx_backend)b));
    if (used > 0 && (size_t)used < sizeof message - 1)
        strcat(message, ")");
    raise_status(where, BPX_ERR_UNKNOWN_BACKEND, message);
    return -1;
}

// Creates a world, naming the reason when its backend or SIMD width cannot run here.
bpx_status create_world(const bpx_world_def *def, bpx_world **world, bpx_error *err)
{
    bpx_status status = bpx_world_create(def, world);
    if (status == BPX_OK)
        return status;
    err->status = status;
    err->index = UINT32_MAX;
    err->axis = -1;
    if (status == BPX_ERR_INVALID_ARGUMENT && bpx_world_def_check(def, err) != BPX_OK)
        return status; // the check names the field
    if (status == BPX_ERR_BACKEND_UNAVAILABLE) {
        bpx_backend_info info = bpx_backend_query(def->backend);
        if (!info.available)
            snprintf(err->message, sizeof err->message, "backend %s: %s", info.name,
                     info.reason);
        else
            snprintf(err->message, sizeof err->message, "SIMD width %s: not supported here",
                     bpx_simd_name(def->simd));
    } else {
        snprintf(err->message, sizeof err->message, "%s", bpx_status_string(status));
    }
    return status;
}

static PyObject *py_last_input_address(PyObject *module, PyObject *unused)
{
    (void)module;
    (void)unused;
    return PyLong_FromSize_t((size_t)last_input_address);
}

static PyObject *py_allocated_bytes(PyObject *module, PyObject *unused)
{
    (void)module;
    (void)unused;
    return PyLong_FromLongLong((long long)bpx_allocated_bytes());
}

static PyObject *py_backends(PyObject *module, PyObject *unused)
{
    (void)module;
    (void)unused;
    PyObject *list = PyList_New(0);
    for (int b = 0; list && b < BPX_BACKEND_COUNT; b++) {
        bpx_backend_info info = bpx_backend_query((bpx_backend)b);
        PyObject *row = Py_BuildValue("(sOss)", info.name, info.available ? Py_True : Py_False,
                                      info.reason ? info.reason : "", info.detail);
        if (!row || PyList_Append(list, row) != 0)
            Py_CLEAR(list);
        Py_XDECREF(row);
    }
    return list;
}

static PyObject *py_simd_widths(PyObject *module, PyObject *unused)
{
    (void)module;
    (void)unused;
    PyObject *list = PyList_New(0);
    for (int s = 0; list && s < BPX_SIMD_COUNT; s++) {
        PyObject *row = Py_BuildValue("(sOi)", bpx_simd_name((bpx_simd)s),
                                      bpx_simd_supported((bpx_simd)s) ? Py_True : Py_False,
                                      bpx_simd_lanes((bpx_simd)s));
        if (!row || PyList_Append(list, row) != 0)
            Py_CLEAR(list);
        Py_XDECREF(row);
    }
    return list;
}

// ---------------------------------------------------------------------------------------------
// World

static int World_init(WorldObject *self, PyObject *args, PyObject *kwargs)
{
    static const char where[] = "World";
    static char *keywords[] = {"backend",       "simd",         "threads",    "track_events",
                               "spin_us",       "capacity_hint", "begin_margin", "end_margin",
                               "period",        "profile",       NULL};
    const char *backend_name = "auto", *simd_name = "auto";
    int threads = 1, track_events = 0, spin_us = 0, profile = 0;
    unsigned long capacity_hint = 0;
    float begin_margin = 0.0f, end_margin = 0.0f;
    double period[3] = {0, 0, 0};
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "|ssipikff(ddd)p", keywords, &backend_name,
                                     &simd_name, &threads, &track_events, &spin_us,
                                     &capacity_hint, &begin_margin, &end_margin, &period[0],
                                     &period[1], &period[2], &profile))
        return -1;
    if (self->world) {
        raise_status(where, BPX_ERR_BAD_STATE, "the world is already initialised");
        return -1;
    }
    bpx_world_def def = bpx_default_world_def();
    if (backend_from_name(where, backend_name, &def.backend) != 0)
        return -1;
    if (bpx_simd_from_name(simd_name, &def.simd) != BPX_OK) {
        char message[96];
        snprintf(message, sizeof message, "no SIMD width named '%s'", simd_name);
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
        return -1;
    }
    def.worker_count = threads;
    def.track_events = track_events != 0;
    def.spin_us = spin_us;
    def.capacity_hint = capacity_hint > BPX_MAX_BOXES ? BPX_MAX_BOXES : (uint32_t)capacity_hint;
    def.begin_margin = begin_margin;
    def.end_margin = end_margin;
    memcpy(def.period, period, sizeof period);
    def.profile = profile != 0;
    if (!self->lock && !(self->lock = PyThread_allocate_lock())) {
        PyErr_NoMemory();
        return -1;
    }
    bpx_error err = {0};
    bpx_world *world = NULL;
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = create_world(&def, &world, &err);
    Py_END_ALLOW_THREADS
    if (status != BPX_OK) {
        raise_error(where, &err);
        return -1;
    }
    self->world = world;
    return 0;
}

static void world_destroy_unlocked(WorldObject *self)
{
    bpx_world *world = self->world;
    self->world = NULL;
    if (world) {
        Py_BEGIN_ALLOW_THREADS
        bpx_world_destroy(world);
        Py_END_ALLOW_THREADS
    }
}

static void World_dealloc(WorldObject *self)
{
    // No method can be running: each holds a reference to self.
    world_destroy_unlocked(self);
    Py_CLEAR(self->pair_filter);
    for (int k = 0; k < 3; k++)
        Py_CLEAR(self->filter_error[k]);
    world_access_free(self);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *World_close(WorldObject *self, PyObject *unused)
{
    (void)unused;
    if (!self->lock || !self->world)
        Py_RETURN_NONE;
    if (world_enter(self, "World.close") != 0) {
        if (self->world)
            return NULL; // from one of the world's own callbacks
        PyErr_Clear(); // closed by another thread meanwhile: closing twice is fine
        Py_RETURN_NONE;
    }
    world_destroy_unlocked(self);
    world_leave(self);
    Py_RETURN_NONE;
}

static PyObject *World_closed(WorldObject *self, void *closure)
{
    (void)closure;
    return PyBool_FromLong(self->world == NULL);
}

// The calls that take one buffer of floats: load_extents (3 per object), update_centres (3 per
// object, as many as loaded) and set_boxes (6 per box).
enum float_call { LOAD_EXTENTS, UPDATE_CENTRES, SET_BOXES };

static PyObject *world_float_call(WorldObject *self, PyObject *obj, enum float_call call)
{
    static const char *const names[] = {"World.load_extents", "World.update_centres",
                                        "World.set_boxes"};
    const char *where = names[call];
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer view;
    uint32_t n;
    if (get_rows(where, obj, 'f', call == SET_BOXES ? 6 : 3, &view, &n) != 0) {
        world_leave(self);
        return NULL;
    }
    if (call == UPDATE_CENTRES && n != bpx_world_box_count(self->world)) {
        // bpx reads as many centres as it has objects: a shorter buffer never gets there. A
        // world not in the two-phase mode says so first, as bpx would.
        if (bpx_world_update_centres(self->world, NULL) == BPX_ERR_BAD_STATE) {
            PyBuffer_Release(&view);
            world_leave(self);
            return raise_error(where, bpx_world_error(self->world));
        }
        char message[96];
        snprintf(message, sizeof message, "%u centres for %u objects", n,
                 bpx_world_box_count(self->world));
        PyBuffer_Release(&view);
        world_leave(self);
        return raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
    }
    last_input_address = (uintptr_t)view.buf;
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    if (call == LOAD_EXTENTS)
        status = bpx_world_load_extents(self->world, view.buf, n);
    else if (call == UPDATE_CENTRES)
        status = bpx_world_update_centres(self->world, view.buf);
    else
        status = bpx_world_set_boxes(self->world, view.buf, n);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    PyObject *result = status == BPX_OK ? Py_NewRef(Py_None)
                                        : raise_error(where, bpx_world_error(self->world));
    world_leave(self);
    return result;
}

static PyObject *World_load_extents(WorldObject *self, PyObject *obj)
{
    return world_float_call(self, obj, LOAD_EXTENTS);
}

static PyObject *World_update_centres(WorldObject *self, PyObject *obj)
{
    return world_float_call(self, obj, UPDATE_CENTRES);
}

static PyObject *World_set_boxes(WorldObject *self, PyObject *obj)
{
    return world_float_call(self, obj, SET_BOXES);
}

static PyObject *World_add_boxes(WorldObject *self, PyObject *obj)
{
    static const char where[] = "World.add";
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer view;
    uint32_t n;
    if (get_rows(where, obj, 'f', 6, &view, &n) != 0) {
        world_leave(self);
        return NULL;
    }
    char *ids = NULL;
    PyObject *out = new_bytes((size_t)n * sizeof(uint32_t), &ids);
    if (out) {
        bpx_status status;
        Py_BEGIN_ALLOW_THREADS
        status = bpx_world_add_boxes(self->world, view.buf, n, (uint32_t *)ids);
        Py_END_ALLOW_THREADS
        if (status != BPX_OK) {
            Py_CLEAR(out);
            raise_error(where, bpx_world_error(self->world));
        }
    }
    PyBuffer_Release(&view);
    world_leave(self);
    return out;
}

static PyObject *World_remove_boxes(WorldObject *self, PyObject *obj)
{
    static const char where[] = "World.remove";
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer view;
    uint32_t n;
    if (get_rows(where, obj, 'I', 1, &view, &n) != 0) {
        world_leave(self);
        return NULL;
    }
    bpx_status status = bpx_world_remove_boxes(self->world, view.buf, n);
    PyBuffer_Release(&view);
    PyObject *result = status == BPX_OK ? Py_NewRef(Py_None)
                                        : raise_error(where, bpx_world_error(self->world));
    world_leave(self);
    return result;
}

static PyObject *World_move_boxes(WorldObject *self, PyObject *args)
{
    static const char where[] = "World.move";
    PyObject *ids_obj, *boxes_obj;
    if (!PyArg_ParseTuple(args, "OO", &ids_obj, &boxes_obj))
        return NULL;
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer ids, boxes;
    uint32_t id_count, box_count;
    if (get_rows(where, ids_obj, 'I', 1, &ids, &id_count) != 0) {
        world_leave(self);
        return NULL;
    }
    if (get_rows(where, boxes_obj, 'f', 6, &boxes, &box_count) != 0) {
        PyBuffer_Release(&ids);
        world_leave(self);
        return NULL;
    }
    PyObject *result = NULL;
    if (id_count != box_count) {
        char message[96];
        snprintf(message, sizeof message, "%u ids for %u boxes", id_count, box_count);
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
    } else {
        bpx_status status;
        Py_BEGIN_ALLOW_THREADS
        status = bpx_world_move_boxes(self->world, ids.buf, boxes.buf, id_count);
        Py_END_ALLOW_THREADS
        result = status == BPX_OK ? Py_NewRef(Py_None)
                                  : raise_error(where, bpx_world_error(self->world));
    }
    PyBuffer_Release(&boxes);
    PyBuffer_Release(&ids);
    world_leave(self);
    return result;
}

static PyObject *World_set_filters(WorldObject *self, PyObject *args)
{
    static const char where[] = "World.set_filters";
    PyObject *objs[3];
    if (!PyArg_ParseTuple(args, "OOO", &objs[0], &objs[1], &objs[2]))
        return NULL;
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer views[3];
    uint32_t counts[3] = {0, 0, 0};
    int got = 0;
    int ids_given = objs[0] != Py_None;
    for (int k = ids_given ? 0 : 1; k < 3; k++, got++) {
        if (get_rows(where, objs[k], 'I', 1, &views[k], &counts[k]) != 0)
            break;
    }
    PyObject *result = NULL;
    if (got == (ids_given ? 3 : 2)) {
        uint32_t count = counts[1];
        if (counts[2] != count || (ids_given && counts[0] != count)) {
            char message[128];
            snprintf(message, sizeof message, "%u ids, %u categories and %u masks differ",
                     ids_given ? counts[0] : count, counts[1], counts[2]);
            raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
        } else {
            bpx_status status = bpx_world_set_filters(
                self->world, ids_given ? views[0].buf : NULL, views[1].buf, views[2].buf, count);
            result = status == BPX_OK ? Py_NewRef(Py_None)
                                      : raise_error(where, bpx_world_error(self->world));
        }
    }
    for (int k = ids_given ? 0 : 1, left = got; left > 0; k++, left--)
        PyBuffer_Release(&views[k]);
    world_leave(self);
    return result;
}

// set_groups (int32 values) and set_user_data (uint64 values): one value per id, ids None for
// 0 .. count-1.
enum column_call { SET_GROUPS, SET_USER_DATA };

static PyObject *world_set_column(WorldObject *self, PyObject *args, enum column_call call)
{
    const char *where = call == SET_GROUPS ? "World.set_groups" : "World.set_user_data";
    PyObject *ids_obj, *values_obj;
    if (!PyArg_ParseTuple(args, "OO", &ids_obj, &values_obj))
        return NULL;
    if (world_enter(self, where) != 0)
        return NULL;
    int ids_given = ids_obj != Py_None;
    Py_buffer ids, values;
    uint32_t id_count = 0, count;
    if (ids_given && get_rows(where, ids_obj, 'I', 1, &ids, &id_count) != 0) {
        world_leave(self);
        return NULL;
    }
    if (get_rows(where, values_obj, call == SET_GROUPS ? 'i' : 'Q', 1, &values, &count) != 0) {
        if (ids_given)
            PyBuffer_Release(&ids);
        world_leave(self);
        return NULL;
    }
    PyObject *result = NULL;
    if (ids_given && id_count != count) {
        char message[96];
        snprintf(message, sizeof message, "%u ids for %u values", id_count, count);
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
    } else {
        const uint32_t *id_data = ids_given ? ids.buf : NULL;
        bpx_status status;
        Py_BEGIN_ALLOW_THREADS
        if (call == SET_GROUPS)
            status = bpx_world_set_groups(self->world, id_data, values.buf, count);
        else
            status = bpx_world_set_user_data(self->world, id_data, values.buf, count);
        Py_END_ALLOW_THREADS
        result = status == BPX_OK ? Py_NewRef(Py_None)
                                  : raise_error(where, bpx_world_error(self->world));
    }
    PyBuffer_Release(&values);
    if (ids_given)
        PyBuffer_Release(&ids);
    world_leave(self);
    return result;
}

static PyObject *World_set_groups(WorldObject *self, PyObject *args)
{
    return world_set_column(self, args, SET_GROUPS);
}

static PyObject *World_set_user_data(WorldObject *self, PyObject *args)
{
    return world_set_column(self, args, SET_USER_DATA);
}

// user_data(ids) -> bytearray of one uint64 per id (0 for an id not in use).
static PyObject *World_user_data(WorldObject *self, PyObject *obj)
{
    static const char where[] = "World.user_data";
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer ids;
    uint32_t count;
    if (get_rows(where, obj, 'I', 1, &ids, &count) != 0) {
        world_leave(self);
        return NULL;
    }
    char *data = NULL;
    PyObject *out = new_bytes((size_t)count * sizeof(uint64_t), &data);
    if (out) {
        const uint32_t *id_data = ids.buf;
        Py_BEGIN_ALLOW_THREADS
        for (uint32_t k = 0; k < count; k++)
            ((uint64_t *)data)[k] = bpx_world_user_data(self->world, id_data[k]);
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&ids);
    world_leave(self);
    return out;
}

// exclude_pairs and include_pairs: (k, 2) uint32 pairs.
static PyObject *world_pairs_call(WorldObject *self, PyObject *obj, int exclude)
{
    const char *where = exclude ? "World.exclude_pairs" : "World.include_pairs";
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer view;
    uint32_t count;
    if (get_rows(where, obj, 'I', 2, &view, &count) != 0) {
        world_leave(self);
        return NULL;
    }
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    if (exclude)
        status = bpx_world_exclude_pairs(self->world, view.buf, count);
    else
        status = bpx_world_include_pairs(self->world, view.buf, count);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    PyObject *result = status == BPX_OK ? Py_NewRef(Py_None)
                                        : raise_error(where, bpx_world_error(self->world));
    world_leave(self);
    return result;
}

static PyObject *World_exclude_pairs(WorldObject *self, PyObject *obj)
{
    return world_pairs_call(self, obj, 1);
}

static PyObject *World_include_pairs(WorldObject *self, PyObject *obj)
{
    return world_pairs_call(self, obj, 0);
}

static PyObject *World_pair_excluded(WorldObject *self, PyObject *args)
{
    static const char where[] = "World.pair_excluded";
    unsigned long long i, j;
    if (!PyArg_ParseTuple(args, "KK", &i, &j))
        return NULL;
    if (i > UINT32_MAX || j > UINT32_MAX)
        return raise_status(where, BPX_ERR_INVALID_ARGUMENT, "an id above 2**32 - 1");
    if (world_enter(self, where) != 0)
        return NULL;
    bool excluded = bpx_world_pair_excluded(self->world, (uint32_t)i, (uint32_t)j);
    world_leave(self);
    return PyBool_FromLong(excluded);
}

static PyObject *World_snapshot(WorldObject *self, PyObject *unused)
{
    (void)unused;
    static const char where[] = "World.snapshot";
    if (world_enter(self, where) != 0)
        return NULL;
    size_t size = 0;
    bpx_status status = bpx_world_snapshot(self->world, NULL, 0, &size);
    PyObject *bytes = NULL;
    if (status == BPX_OK || status == BPX_ERR_CAPACITY) {
        bytes = PyBytes_FromStringAndSize(NULL, (Py_ssize_t)size);
        if (bytes) {
            Py_BEGIN_ALLOW_THREADS
            status = bpx_world_snapshot(self->world, PyBytes_AS_STRING(bytes), size, &size);
            Py_END_ALLOW_THREADS
        }
    }
    if (status != BPX_OK && !PyErr_Occurred()) {
        Py_CLEAR(bytes);
        raise_status(where, status,
                     status == BPX_ERR_BAD_STATE
                         ? "the world holds float64 boxes (set_boxes with values float32 does "
                           "not hold) or boxes in a device buffer, which snapshots do not carry"
                         : "the world's state could not be written");
    }
    world_leave(self);
    return bytes;
}

static PyObject *World_restore(WorldObject *self, PyObject *arg)
{
    static const char where[] = "World.restore";
    Py_buffer view;
    if (PyObject_GetBuffer(arg, &view, PyBUF_SIMPLE) != 0)
        return NULL;
    if (world_enter(self, where) != 0) {
        PyBuffer_Release(&view);
        return NULL;
    }
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = bpx_world_restore(self->world, view.buf, (size_t)view.len);
    Py_END_ALLOW_THREADS
    PyObject *result = status == BPX_OK ? Py_NewRef(Py_None)
                                        : raise_error(where, bpx_world_error(self->world));
    PyBuffer_Release(&view);
    world_leave(self);
    return result;
}

// bpx_pair_filter_fn for a Python callable: collide runs without the GIL, on the calling
// thread, so the GIL is taken back for each call. After an exception the cycle's other new
// pairs are refused without asking, and collide raises it.
static bool call_pair_filter(uint32_t i, uint32_t j, uint64_t data_i, uint64_t data_j,
                             void *context)
{
    WorldObject *self = context;
    PyGILState_STATE gil = PyGILState_Ensure();
    bool accept = false;
    if (!self->filter_error[0]) {
        self->filter_thread = PyThread_get_thread_ident();
        PyObject *answer =
            PyObject_CallFunction(self->pair_filter, "IIKK", i, j, (unsigned long long)data_i,
                                  (unsigned long long)data_j);
        self->filter_thread = 0;
        int truth = answer ? PyObject_IsTrue(answer) : -1;
        Py_XDECREF(answer);
        if (truth < 0)
            PyErr_Fetch(&self->filter_error[0], &self->filter_error[1], &self->filter_error[2]);
        accept = truth == 1;
    }
    PyGILState_Release(gil);
    return accept;
}

static PyObject *World_set_pair_filter(WorldObject *self, PyObject *fn)
{
    static const char where[] = "World.set_pair_filter";
    if (fn != Py_None && !PyCallable_Check(fn))
        return raise_status(where, BPX_ERR_INVALID_ARGUMENT, "the filter must be callable or None");
    if (world_enter(self, where) != 0)
        return NULL;
    bpx_status status = bpx_world_set_pair_filter(self->world, fn == Py_None ? NULL : call_pair_filter,
                                                  fn == Py_None ? NULL : self);
    PyObject *result = NULL;
    if (status == BPX_OK) {
        Py_XSETREF(self->pair_filter, fn == Py_None ? NULL : Py_NewRef(fn));
        result = Py_NewRef(Py_None);
    } else {
        result = raise_error(where, bpx_world_error(self->world));
    }
    world_leave(self);
    return result;
}

static PyObject *World_stats(WorldObject *self, PyObject *unused)
{
    (void)unused;
    if (world_enter(self, "World.stats") != 0)
        return NULL;
    bpx_cycle_stats s = bpx_world_stats(self->world);
    const char *backend = bpx_backend_name(bpx_world_backend(self->world));
    const char *simd = bpx_simd_name(bpx_world_simd(self->world));
    world_leave(self);
    // The profiled stages (World(profile=True)) as tuples in the order they ran.
    static const char *const access_names[] = {"sequential", "gather", "scatter"};
    PyObject *stages = PyTuple_New(s.stage_count);
    for (uint32_t k = 0; stages && k < s.stage_count; k++) {
        const bpx_stage_stats *t = &s.stages[k];
        PyObject *stage = Py_BuildValue(
            "(ssKKKKs)", t->name, t->backend, (unsigned long long)t->ns,
            (unsigned long long)t->bytes_read, (unsigned long long)t->bytes_written,
            (unsigned long long)t->random,
            (unsigned)t->access < 3 ? access_names[t->access] : "sequential");
        if (!stage) {
            Py_CLEAR(stages);
            break;
        }
        PyTuple_SET_ITEM(stages, k, stage);
    }
    if (!stages)
        return NULL;
    return Py_BuildValue("{s:k,s:K,s:K,s:K,s:K,s:K,s:K,s:O,s:K,s:K,s:K,s:K,s:K,s:s,s:s,s:d,s:N}",
                         "box_count", (unsigned long)s.box_count, "pair_count",
                         (unsigned long long)s.pair_count, "pair_tests",
                         (unsigned long long)s.pair_tests, "update_ns",
                         (unsigned long long)s.update_ns, "compare_ns",
                         (unsigned long long)s.compare_ns, "emit_ns",
                         (unsigned long long)s.emit_ns, "cycle_count",
                         (unsigned long long)s.cycle_count, "rebuilt",
                         s.rebuilt ? Py_True : Py_False, "transfer_in_ns",
                         (unsigned long long)s.transfer_in_ns, "transfer_out_ns",
                         (unsigned long long)s.transfer_out_ns, "device_ns",
                         (unsigned long long)s.device_ns, "bytes_in",
                         (unsigned long long)s.bytes_in, "bytes_out",
                         (unsigned long long)s.bytes_out, "backend", backend, "simd", simd,
                         "device_share", (double)s.device_share, "stages", stages);
}

static PyObject *World_box_count(WorldObject *self, PyObject *unused)
{
    (void)unused;
    if (world_enter(self, "World.box_count") != 0)
        return NULL;
    uint32_t n = bpx_world_box_count(self->world);
    world_leave(self);
    return PyLong_FromUnsignedLong(n);
}

static PyMethodDef World_methods[] = {
    {"close", (PyCFunction)World_close, METH_NOARGS, "Destroys the C world; idempotent."},
    {"snapshot", (PyCFunction)World_snapshot, METH_NOARGS, "bpx_world_snapshot -> bytes"},
    {"restore", (PyCFunction)World_restore, METH_O, "bpx_world_restore(bytes-like)"},
    {"load_extents", (PyCFunction)World_load_extents, METH_O, "bpx_world_load_extents"},
    {"update_centres", (PyCFunction)World_update_centres, METH_O, "bpx_world_update_centres"},
    {"set_boxes", (PyCFunction)World_set_boxes, METH_O, "bpx_world_set_boxes"},
    {"set_boxes64", (PyCFunction)World_set_boxes64, METH_O, "bpx_world_set_boxes64"},
    {"add_boxes", (PyCFunction)World_add_boxes, METH_O, "bpx_world_add_boxes -> ids"},
    {"remove_boxes", (PyCFunction)World_remove_boxes, METH_O, "bpx_world_remove_boxes"},
    {"move_boxes", (PyCFunction)World_move_boxes, METH_VARARGS, "bpx_world_move_boxes"},
    {"set_filters", (PyCFunction)World_set_filters, METH_VARARGS, "bpx_world_set_filters"},
    {"set_groups", (PyCFunction)World_set_groups, METH_VARARGS, "bpx_world_set_groups"},
    {"exclude_pairs", (PyCFunction)World_exclude_pairs, METH_O, "bpx_world_exclude_pairs"},
    {"include_pairs", (PyCFunction)World_include_pairs, METH_O, "bpx_world_include_pairs"},
    {"pair_excluded", (PyCFunction)World_pair_excluded, METH_VARARGS,
     "bpx_world_pair_excluded -> bool"},
    {"set_user_data", (PyCFunction)World_set_user_data, METH_VARARGS,
     "bpx_world_set_user_data"},
    {"user_data", (PyCFunction)World_user_data, METH_O,
     "bpx_world_user_data for each id -> bytearray of uint64"},
    {"collide", (PyCFunction)World_collide, METH_NOARGS, "bpx_world_collide -> pairs"},
    {"set_pair_filter", (PyCFunction)World_set_pair_filter, METH_O,
     "bpx_world_set_pair_filter(callable(i, j, user_data_i, user_data_j) -> bool, or None)"},
    {"pairs", (PyCFunction)World_pairs, METH_NOARGS, "bpx_world_pairs (a copy)"},
    {"image_pairs", (PyCFunction)World_image_pairs, METH_NOARGS,
     "bpx_world_image_pairs -> (i, j, shifts) as bytes"},
    {"period", (PyCFunction)World_period, METH_NOARGS, "bpx_world_period -> (x, y, z)"},
    {"events", (PyCFunction)World_events, METH_NOARGS, "bpx_world_pair_events (copies)"},
    {"stats", (PyCFunction)World_stats, METH_NOARGS, "bpx_world_stats as a dict"},
    {"box_count", (PyCFunction)World_box_count, METH_NOARGS, "bpx_world_box_count"},
    {"query", (PyCFunction)World_query, METH_VARARGS,
     "query(kind, closest, any, params, categories, masks, batch): bpx_world_query(_batch)"},
    {"query_stats", (PyCFunction)World_query_stats, METH_NOARGS,
     "bpx_world_query_stats as a dict"},
    {"prepare_queries", (PyCFunction)World_prepare_queries, METH_NOARGS,
     "bpx_world_prepare_queries"},
    {"query_shared", (PyCFunction)World_query_shared, METH_VARARGS,
     "query_shared(kind, closest, any, params, category, mask): bpx_world_query_shared"},
    {"query_each", (PyCFunction)World_query_each, METH_VARARGS,
     "query_each(kind, params, category, mask, fn, shared): bpx_world_query_each"},
    {NULL, NULL, 0, NULL}};

static PyGetSetDef World_getset[] = {
    {"closed", (getter)World_closed, NULL, "Whether close() has run.", NULL},
    {NULL, NULL, NULL, NULL, NULL}};

static PyTypeObject WorldType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "bpx._bpx.World",
    .tp_doc = PyDoc_STR("A bpx_world; see bpx.World for the documented interface."),
    .tp_basicsize = sizeof(WorldObject),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)World_init,
    .tp_dealloc = (destructor)World_dealloc,
    .tp_methods = World_methods,
    .tp_getset = World_getset,
};

// ---------------------------------------------------------------------------------------------
// Module

static PyMethodDef module_methods[] = {
    {"find_pairs", py_find_pairs, METH_VARARGS, find_pairs_doc},
    {"find_neighbors", py_find_neighbors, METH_VARARGS,
     "find_neighbors(where, data, format, period, cutoff, metric, want_distances, pairs_only, "
     "backend, threads[, cell]) -> (pairs bytearray, distances bytearray or None); cell: None "
     "or ((a), (b), (c), (open a, b, c)), a triclinic cell for points"},
    {"backends", py_backends, METH_NOARGS, "[(name, available, reason, detail)]"},
    {"simd_widths", py_simd_widths, METH_NOARGS, "[(name, supported, lanes)]"},
    {"_last_input_address", py_last_input_address, METH_NOARGS,
     "Address of the last float buffer handed to bpx (for zero-copy tests)."},
    {"_allocated_bytes", py_allocated_bytes, METH_NOARGS,
     "Bytes bpx holds over all worlds (bpx_allocated_bytes; for leak tests)."},
    {"_set_max_pairs", py_set_max_pairs, METH_O, "_set_max_pairs(count) -> previous (tests)."},
    {"_time_c_find_pairs", py_time_c_find_pairs, METH_VARARGS,
     "_time_c_find_pairs(boxes, backend, repeats) -> ns: fastest bpx_find_pairs call in C."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, .m_name = "bpx._bpx",
    .m_doc = "The C layer of bpx; use the bpx package.", .m_size = -1,
    .m_methods = module_methods};

PyMODINIT_FUNC PyInit__bpx(void)
{
    if (!error_factory) {
        PyObject *errors = PyImport_ImportModule("bpx._errors");
        if (!errors)
            return NULL;
        error_factory = PyObject_GetAttrString(errors, "_from_status");
        Py_DECREF(errors);
        if (!error_factory)
            return NULL;
    }
    if (PyType_Ready(&WorldType) < 0)
        return NULL;
    PyObject *module = PyModule_Create(&module_def);
    if (!module)
        return NULL;
    Py_INCREF(&WorldType);
    if (PyModule_AddObject(module, "World", (PyObject *)&WorldType) < 0 ||
        PyModule_AddStringConstant(module, "version", bpx_version()) < 0 ||
        PyModule_AddIntConstant(module, "MAX_BOXES", BPX_MAX_BOXES) < 0 ||
        add_query_constants(module) < 0) {
        Py_DECREF(&WorldType);
        Py_DECREF(module);
        return NULL;
    }
    return module;
}
