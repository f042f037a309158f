// bpx for Python: the query methods of bpx._bpx.World (include/bpx/query.h), over the same
// buffers and errors as the rest of the module (_bpx.h). SPDX-License-Identifier: MIT
#include "_bpx.h"

#include <stdio.h>
#include <string.h>

// The floats of one query, per kind, in the buffer the Python layer builds (bpx/_world.py):
//   BOX      box min x, y, z, max x, y, z                                           6
//   SPHERE   centre x, y, z, radius                                                 4
//   RAY      origin x, y, z, direction x, y, z, max_fraction                        7
//   SWEEP    box min x, y, z, max x, y, z, translation x, y, z, max_fraction        10
//   ORIENTED centre x, y, z, half extents x, y, z, rotation (row-major 3x3)         15
//   POINT    point x, y, z (Python's kind QUERY_POINT: bpx_query_point, a box query) 3
static const Py_ssize_t query_floats[PY_QUERY_KINDS] = {6, 4, 7, 10, 15, 3};

static const char *const query_names[2][PY_QUERY_KINDS] = {
    {"World.query_box", "World.query_sphere", "World.ray_cast", "World.sweep",
     "World.query_oriented", "World.query_point"},
    {"World.query_box_batch", "World.query_sphere_batch", "World.ray_cast_batch",
     "World.sweep_batch", "World.query_oriented_batch", "World.query_point_batch"}};

const char *query_name(int kind, int batch)
{
    return kind >= 0 && kind < PY_QUERY_KINDS ? query_names[batch != 0][kind] : "World.query";
}

// Raises a query's error. bpx names the query by its index ("query 5: origin x is nan"); a
// single query's message drops "query 0: " ("query: " from the shared queries) and its index,
// the method's name being enough.
PyObject *raise_query_error(const char *where, const bpx_error *error, int batch)
{
    bpx_error err = *error;
    static const char *const prefixes[] = {"query 0: ", "query: "};
    if (!batch && (err.index == 0 || err.index == UINT32_MAX)) {
        err.index = UINT32_MAX;
        for (int k = 0; k < 2; k++) {
            size_t length = strlen(prefixes[k]);
            if (strncmp(err.message, prefixes[k], length) == 0)
                memmove(err.message, err.message + length, strlen(err.message) - length + 1);
        }
    }
    return raise_error(where, &err);
}

typedef struct query_fill {
    int kind; // a Python kind: bpx's, or PY_QUERY_POINT
    bool closest, any;
    const float *params;
    const uint32_t *categories, *masks; // 1 value (for every query) or one per query
    uint32_t category_count, mask_count;
} query_fill;

static void fill_queries(const query_fill *f, bpx_query *queries, uint32_t count)
{
    Py_ssize_t stride = query_floats[f->kind];
    // fill's kind is the Python kind (PY_QUERY_POINT among them); each query gets bpx's.
    for (uint32_t k = 0; k < count; k++) {
        const float *p = f->params + (size_t)k * (size_t)stride;
        bpx_query *q = &queries[k];
        memset(q, 0, sizeof *q);
        q->kind = (bpx_query_kind)f->kind;
        q->closest = f->closest;
        q->any = f->any;
        q->filter.category = f->categories[f->category_count == 1 ? 0 : k];
        q->filter.mask = f->masks[f->mask_count == 1 ? 0 : k];
        switch (f->kind) {
        case BPX_QUERY_BOX:
            memcpy(&q->box, p, sizeof q->box);
            break;
        case BPX_QUERY_SPHERE:
            memcpy(q->centre, p, sizeof q->centre);
            q->radius = p[3];
            break;
        case BPX_QUERY_RAY:
            memcpy(q->origin, p, sizeof q->origin);
            memcpy(q->direction, p + 3, sizeof q->direction);
            q->max_fraction = p[6];
            break;
        case BPX_QUERY_SWEEP:
            memcpy(&q->box, p, sizeof q->box);
            memcpy(q->direction, p + 6, sizeof q->direction);
            q->max_fraction = p[9];
            break;
        case BPX_QUERY_ORIENTED:
            memcpy(q->centre, p, sizeof q->centre);
            memcpy(q->half_extents, p + 3, sizeof q->half_extents);
            memcpy(q->rotation, p + 6, sizeof q->rotation);
            break;
        default: // PY_QUERY_POINT: bpx_query_point's box [point, point]
            q->kind = BPX_QUERY_BOX;
            memcpy(q->box.min, p, sizeof q->box.min);
            memcpy(q->box.max, p, sizeof q->box.max);
            break;
        }
    }
}

// World.query(kind, closest, any, params, categories, masks, batch)
//   -> (ids, fractions or None)                     batch false: exactly one query
//   -> (offsets, ids, fractions or None)            batch true: CSR over the queries
// closest (rays and sweeps): the closest hit only; any (every kind): at most one hit, the first
// the walk of the tree meets; bpx refuses the two together (INVALID_ARGUMENT).
// ids are uint32, fractions float32 (rays and sweeps only), offsets size_t (count + 1). bpx runs
// the queries into its own buffer (capacity 0: CAPACITY with the total, nothing written), the
// hits are read back with bpx_world_query_hits and split into ids and fractions, with the GIL
// released throughout and the world's lock held, which keeps bpx's hits valid meanwhile.
PyObject *World_query(WorldObject *self, PyObject *args)
{
    int kind, closest, any, batch;
    PyObject *params_obj, *categories_obj, *masks_obj;
    if (!PyArg_ParseTuple(args, "ippOOOp", &kind, &closest, &any, &params_obj, &categories_obj,
                          &masks_obj, &batch))
        return NULL;
    if (kind < 0 || kind >= PY_QUERY_KINDS)
        return raise_status("World.query", BPX_ERR_INVALID_ARGUMENT, "unknown query kind");
    const char *where = query_name(kind, batch);
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer views[3];
    uint32_t counts[3];
    PyObject *objs[3] = {params_obj, categories_obj, masks_obj};
    int got = 0;
    for (; got < 3; got++)
        if (get_rows(where, objs[got], got ? 'I' : 'f', got ? 1 : query_floats[kind], &views[got],
                     &counts[got]) != 0)
            break;
    PyObject *result = NULL, *offsets_out = NULL, *ids_out = NULL, *fractions_out = NULL;
    bpx_query *queries = NULL;
    uint32_t count = got == 3 ? counts[0] : 0;
    if (got < 3)
        goto done;
    if (!batch && count != 1) {
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, "expected one query");
        goto done;
    }
    if (counts[1] != 1 && counts[1] != count) {
        char message[96];
        snprintf(message, sizeof message, "%u categories for %u queries", counts[1], count);
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
        goto done;
    }
    if (counts[2] != 1 && counts[2] != count) {
        char message[96];
        snprintf(message, sizeof message, "%u masks for %u queries", counts[2], count);
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, message);
        goto done;
    }
    queries = PyMem_RawMalloc(count ? (size_t)count * sizeof(bpx_query) : 1);
    if (!queries) {
        PyErr_NoMemory();
        goto done;
    }
    size_t single_offsets[2];
    size_t *offsets = single_offsets;
    if (batch) {
        char *data = NULL;
        offsets_out = new_bytes(((size_t)count + 1) * sizeof(size_t), &data);
        if (!offsets_out)
            goto done;
        offsets = (size_t *)data;
    }
    query_fill fill = {kind, closest != 0, any != 0, views[0].buf, views[1].buf,
                       views[2].buf, counts[1], counts[2]};
    size_t total = 0;
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    fill_queries(&fill, queries, count);
    if (batch)
        status = bpx_world_query_batch(self->world, queries, count, offsets, NULL, 0, &total);
    else
        status = bpx_world_query(self->world, queries, NULL, 0, &total);
    Py_END_ALLOW_THREADS
    if (status != BPX_OK && status != BPX_ERR_CAPACITY) {
        raise_query_error(where, bpx_world_error(self->world), batch);
        goto done;
    }
    char *ids = NULL, *fractions = NULL;
    ids_out = new_bytes(total * sizeof(uint32_t), &ids);
    if (!ids_out)
        goto done;
    int with_fractions = kind == BPX_QUERY_RAY || kind == BPX_QUERY_SWEEP;
    if (with_fractions && !(fractions_out = new_bytes(total * sizeof(float), &fractions)))
        goto done;
    size_t read = 0;
    const bpx_hit *hits = bpx_world_query_hits(self->world, NULL, NULL, &read);
    if (read != total || (total && !hits)) {
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, "the hits could not be read back");
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    for (size_t h = 0; h < total; h++)
        ((uint32_t *)ids)[h] = hits[h].id;
    for (size_t h = 0; fractions && h < total; h++)
        ((float *)fractions)[h] = hits[h].fraction;
    Py_END_ALLOW_THREADS
    PyObject *none = Py_None;
    if (batch)
        result = PyTuple_Pack(3, offsets_out, ids_out, fractions_out ? fractions_out : none);
    else
        result = PyTuple_Pack(2, ids_out, fractions_out ? fractions_out : none);
done:
    Py_XDECREF(offsets_out);
    Py_XDECREF(ids_out);
    Py_XDECREF(fractions_out);
    PyMem_RawFree(queries);
    for (int k = 0; k < got; k++)
        PyBuffer_Release(&views[k]);
    world_leave(self);
    return result;
}

int one_query(const char *where, int kind, int closest, int any, PyObject *params_obj,
              PyObject *category_obj, PyObject *mask_obj, bpx_query *query)
{
    if (kind < 0 || kind >= PY_QUERY_KINDS) {
        raise_status(where, BPX_ERR_INVALID_ARGUMENT, "unknown query kind");
        return -1;
    }
    Py_buffer views[3];
    uint32_t counts[3];
    PyObject *objs[3] = {params_obj, category_obj, mask_obj};
    int got = 0;
    for (; got < 3; got++)
        if (get_rows(where, objs[got], got ? 'I' : 'f', got ? 1 : query_floats[kind], &views[got],
                     &counts[got]) != 0)
            break;
    int result = -1;
    if (got == 3 && (counts[0] != 1 || counts[1] != 1 || counts[2] != 1)) {
        raise_status(where, BPX_ERR_INVALID_ARGUMENT,
                     "expected one query, one category and one mask");
    } else if (got == 3) {
        query_fill fill = {kind, closest != 0, any != 0, views[0].buf, views[1].buf,
                           views[2].buf, 1, 1};
        fill_queries(&fill, query, 1);
        result = 0;
    }
    for (int k = 0; k < got; k++)
        PyBuffer_Release(&views[k]);
    return result;
}

PyObject *hits_result(const bpx_hit *hits, size_t count, int kind)
{
    char *ids = NULL, *fractions = NULL;
    PyObject *ids_out = new_bytes(count * sizeof(uint32_t), &ids), *fractions_out = NULL;
    if (!ids_out)
        return NULL;
    if ((kind == BPX_QUERY_RAY || kind == BPX_QUERY_SWEEP) &&
        !(fractions_out = new_bytes(count * sizeof(float), &fractions))) {
        Py_DECREF(ids_out);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    for (size_t h = 0; h < count; h++)
        ((uint32_t *)ids)[h] = hits[h].id;
    for (size_t h = 0; fractions && h < count; h++)
        ((float *)fractions)[h] = hits[h].fraction;
    Py_END_ALLOW_THREADS
    PyObject *result = PyTuple_Pack(2, ids_out, fractions_out ? fractions_out : Py_None);
    Py_DECREF(ids_out);
    Py_XDECREF(fractions_out);
    return result;
}

PyObject *World_query_stats(WorldObject *self, PyObject *unused)
{
    (void)unused;
    if (world_enter(self, "World.query_stats") != 0)
        return NULL;
    bpx_query_stats s = bpx_world_query_stats(self->world);
    world_leave(self);
    return Py_BuildValue("{s:K,s:K,s:k,s:k,s:K}", "builds", (unsigned long long)s.builds,
                         "refits", (unsigned long long)s.refits, "nodes",
                         (unsigned long)s.nodes, "boxes", (unsigned long)s.boxes,
                         "last_update_ns", (unsigned long long)s.last_update_ns);
}

int add_query_constants(PyObject *module)
{
    if (PyModule_AddIntConstant(module, "QUERY_BOX", BPX_QUERY_BOX) < 0 ||
        PyModule_AddIntConstant(module, "QUERY_SPHERE", BPX_QUERY_SPHERE) < 0 ||
        PyModule_AddIntConstant(module, "QUERY_RAY", BPX_QUERY_RAY) < 0 ||
        PyModule_AddIntConstant(module, "QUERY_SWEEP", BPX_QUERY_SWEEP) < 0 ||
        PyModule_AddIntConstant(module, "QUERY_ORIENTED", BPX_QUERY_ORIENTED) < 0 ||
        PyModule_AddIntConstant(module, "QUERY_POINT", PY_QUERY_POINT) < 0)
        return -1;
    return 0;
}
