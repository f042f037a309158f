// bpx for Python: bpx_find_neighbors (periodic images, cutoffs, float64 input) for the
// package's neighbor_pairs and its exact float64 find_pairs. SPDX-License-Identifier: MIT
#include "_bpx.h"

#include <string.h>

// Image pairs as the columns i, j (uint32) and the shifts (3 int32 a pair), bytearrays, split
// here so that NumPy takes them as they are.
PyObject *image_pair_columns(const bpx_image_pair *pairs, size_t count)
{
    char *i = NULL, *j = NULL, *shifts = NULL;
    PyObject *columns[3] = {new_bytes(count * sizeof(uint32_t), &i),
                            new_bytes(count * sizeof(uint32_t), &j),
                            new_bytes(count * 3 * sizeof(int32_t), &shifts)};
    if (!columns[0] || !columns[1] || !columns[2]) {
        for (int c = 0; c < 3; c++)
            Py_XDECREF(columns[c]);
        return NULL;
    }
    for (size_t k = 0; k < count; k++) {
        ((uint32_t *)i)[k] = pairs[k].i;
        ((uint32_t *)j)[k] = pairs[k].j;
        memcpy((int32_t *)shifts + 3 * k, pairs[k].shift, sizeof pairs[k].shift);
    }
    PyObject *out = PyTuple_Pack(3, columns[0], columns[1], columns[2]);
    for (int c = 0; c < 3; c++)
        Py_DECREF(columns[c]);
    return out;
}

// The list's pairs as bytearrays: (i, j) rows of bpx_pair when pairs_only, else the columns.
static PyObject *pairs_bytes(const bpx_neighbor_list *list, int pairs_only)
{
    if (pairs_only) {
        char *data = NULL;
        PyObject *out = new_bytes(list->count * sizeof(bpx_pair), &data);
        if (out)
            for (size_t k = 0; k < list->count; k++)
                ((bpx_pair *)data)[k] = (bpx_pair){list->pairs[k].i, list->pairs[k].j};
        return out;
    }
    return image_pair_columns(list->pairs, list->count);
}

PyObject *py_find_neighbors(PyObject *module, PyObject *args)
{
    (void)module;
    const char *where;
    PyObject *obj;
    bpx_neighbor_def def = bpx_default_neighbor_def();
    int format, metric, want_distances, pairs_only;
    const char *backend_name;
    PyObject *cell = Py_None;
    if (!PyArg_ParseTuple(args, "sOi(ddd)dippsi|O", &where, &obj, &format, &def.period[0],
                          &def.period[1], &def.period[2], &def.cutoff, &metric, &want_distances,
                          &pairs_only, &backend_name, &def.worker_count, &cell))
        return NULL;
    // A triclinic cell: ((a), (b), (c), (open a, open b, open c)), rows as lattice vectors.
    int open[3] = {0, 0, 0};
    if (cell != Py_None &&
        !PyArg_ParseTuple(cell, "(ddd)(ddd)(ddd)(ppp)", &def.cell[0][0], &def.cell[0][1],
                          &def.cell[0][2], &def.cell[1][0], &def.cell[1][1], &def.cell[1][2],
                          &def.cell[2][0], &def.cell[2][1], &def.cell[2][2], &open[0], &open[1],
                          &open[2]))
        return NULL;
    for (int a = 0; a < 3; a++)
        def.cell_open[a] = open[a] != 0;
    if (format < BPX_BOXES_F32 || format > BPX_POINTS_F64)
        return raise_status(where, BPX_ERR_INVALID_ARGUMENT, "unknown input format");
    def.format = (bpx_input_format)format;
    def.metric = (bpx_metric)metric;
    def.want_distances = want_distances != 0;
    if (backend_from_name(where, backend_name, &def.backend) != 0)
        return NULL;
    bool f64 = format == BPX_BOXES_F64 || format == BPX_POINTS_F64;
    bool points = format == BPX_POINTS_F32 || format == BPX_POINTS_F64;
    Py_buffer view;
    uint32_t n;
    if (get_rows(where, obj, f64 ? 'd' : 'f', points ? 3 : 6, &view, &n) != 0)
        return NULL;
    bpx_neighbor_list list;
    bpx_error err = {0};
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = bpx_find_neighbors(&def, view.buf, n, &list, &err);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    if (status != BPX_OK)
        return raise_error(where, &err);
    PyObject *pairs = pairs_bytes(&list, pairs_only);
    PyObject *distances = NULL;
    if (pairs && want_distances) {
        char *data = NULL;
        distances = new_bytes(list.count * sizeof(double), &data);
        if (distances && list.count)
            memcpy(data, list.distances, list.count * sizeof(double));
    } else if (pairs) {
        distances = Py_NewRef(Py_None);
    }
    bpx_neighbor_list_free(&list);
    if (!pairs || !distances) {
        Py_XDECREF(pairs);
        Py_XDECREF(distances);
        return NULL;
    }
    PyObject *out = PyTuple_Pack(2, pairs, distances);
    Py_DECREF(pairs);
    Py_DECREF(distances);
    return out;
}

PyObject *World_image_pairs(WorldObject *self, PyObject *unused)
{
    (void)unused;
    static const char where[] = "World.image_pairs";
    if (world_enter(self, where) != 0)
        return NULL;
    size_t count = 0;
    const bpx_image_pair *pairs = bpx_world_image_pairs(self->world, &count);
    PyObject *out;
    if (!pairs && bpx_world_error(self->world)->status == BPX_ERR_OUT_OF_MEMORY)
        out = raise_error(where, bpx_world_error(self->world));
    else
        out = image_pair_columns(pairs, count);
    world_leave(self);
    return out;
}

PyObject *World_period(WorldObject *self, PyObject *unused)
{
    (void)unused;
    static const char where[] = "World.period";
    if (world_enter(self, where) != 0)
        return NULL;
    double period[3];
    bpx_world_period(self->world, period);
    world_leave(self);
    return Py_BuildValue("(ddd)", period[0], period[1], period[2]);
}

// set_boxes64(float64 (n, 6)): bpx_world_set_boxes64, the world's exact float64 mode.
PyObject *World_set_boxes64(WorldObject *self, PyObject *obj)
{
    static const char where[] = "World.set_boxes";
    if (world_enter(self, where) != 0)
        return NULL;
    Py_buffer view;
    uint32_t n;
    if (get_rows(where, obj, 'd', 6, &view, &n) != 0) {
        world_leave(self);
        return NULL;
    }
    bpx_status status;
    Py_BEGIN_ALLOW_THREADS
    status = bpx_world_set_boxes64(self->world, view.buf, n);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    PyObject *result = status == BPX_OK ? Py_NewRef(Py_None)
                                        : raise_error(where, bpx_world_error(self->world));
    world_leave(self);
    return result;
}
