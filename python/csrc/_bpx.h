// bpx for Python: what the extension module's C files share. SPDX-License-Identifier: MIT
//
// _bpx.c holds the errors, the buffers, the World type and the module; access.c the world's
// lock and its shared readers; pairs.c what returns pairs; query.c the query methods of World
// and the QUERY_* constants; prepared.c the queries of a prepared world. Everything here has
// hidden visibility (the module exports PyInit__bpx alone).
#pragma once

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <pythread.h>

#include <bpx/bpx.h>

#if PY_VERSION_HEX < 0x030A0000 // Python 3.9
static inline PyObject *Py_NewRef(PyObject *object)
{
    Py_INCREF(object);
    return object;
}
#endif

/// A bpx_world and the lock that lets one thread at a time use it.
typedef struct {
    PyObject_HEAD
    bpx_world *world;
    PyThread_type_lock lock;
    PyObject *pair_filter;  // the callable of set_pair_filter, or NULL
    unsigned long filter_thread; // the thread running the pair filter now, else 0
    PyObject *filter_error[3]; // an exception the filter raised in a collide (PyErr_Fetch's
                               // type, value, traceback), raised after it
    Py_ssize_t readers;        // shared queries running now (access.c; read and written with
                               // the GIL held)
    PyThread_type_lock drained; // held while readers > 0: what a call that changes the world
                                // waits on
} WorldObject;

/// The query kinds of World.query: bpx's (BOX .. ORIENTED) and a point, which bpx runs as the
/// box [point, point] (bpx_query_point).
enum { PY_QUERY_POINT = BPX_QUERY_KIND_COUNT, PY_QUERY_KINDS };

// _bpx.c

/// Raises the bpx.Error subclass for err (where names the Python call); returns NULL.
PyObject *raise_error(const char *where, const bpx_error *err);
/// Raises an error that bpx itself did not report, as the bpx.Error subclass of status.
PyObject *raise_status(const char *where, bpx_status status, const char *message);
/// Borrows obj's memory as C-contiguous rows of items_per_row items ('f' float32, 'I' uint32,
/// 'i' int32, 'Q' uint64, 'd' float64); on failure raises and returns -1 with nothing held.
int get_rows(const char *where, PyObject *obj, char kind, Py_ssize_t items_per_row, Py_buffer *view,
             uint32_t *rows);
/// Parses a backend name; on failure raises UnknownBackendError listing the names, returns -1.
int backend_from_name(const char *where, const char *name, bpx_backend *backend);
// Creates a world, naming the reason when its backend or SIMD width cannot run here.
bpx_status create_world(const bpx_world_def *def, bpx_world **world, bpx_error *err);
// Address of the last box buffer handed to bpx (the no-copy tests read it).
extern uintptr_t last_input_address;
/// A new uninitialised bytearray of size bytes; *data receives its memory.
PyObject *new_bytes(size_t size, char **data);

// access.c: who may use a world when

/// Takes the world's lock for a call that may change the world, waiting (GIL released) for
/// another thread's call and for the shared queries running; StateError once closed or from
/// one of the world's own callbacks. world_leave gives it back.
int world_enter(WorldObject *self, const char *where);
void world_leave(WorldObject *self);
/// Joins the shared queries (which read the world only, any number at once, the GIL released):
/// waits for a call that holds the lock, never for another shared query. reader_leave ends it.
int reader_enter(WorldObject *self, const char *where);
void reader_leave(WorldObject *self);
/// A Python callback of self running on this thread (query_each's): world_enter and
/// reader_enter from it raise StateError instead of waiting on a call that waits on them.
typedef struct callback_frame {
    const WorldObject *world;
    struct callback_frame *outer;
} callback_frame;
void callback_begin(callback_frame *frame, const WorldObject *world);
void callback_end(callback_frame *frame);
/// Frees what access.c allocated for the world (World's dealloc).
void world_access_free(WorldObject *self);

// pairs.c

/// Runs a cycle into a new bytearray of pairs (the world's lock held; the GIL released around
/// bpx's work); TooManyPairsError when the count is past what one array can hold.
PyObject *collide_to_bytes(const char *where, bpx_world *world);
/// World.collide(), World.pairs(), World.events().
PyObject *World_collide(WorldObject *self, PyObject *unused);
PyObject *World_pairs(WorldObject *self, PyObject *unused);
extern const char find_pairs_doc[];
PyObject *py_find_pairs(PyObject *module, PyObject *args);
PyObject *py_time_c_find_pairs(PyObject *module, PyObject *args);
PyObject *World_image_pairs(WorldObject *self, PyObject *unused);
PyObject *World_period(WorldObject *self, PyObject *unused);
PyObject *World_set_boxes64(WorldObject *self, PyObject *obj);
PyObject *World_events(WorldObject *self, PyObject *unused);
/// _set_max_pairs(count) -> previous: lowers the pair limit for the tests (0: the real one).
PyObject *py_set_max_pairs(PyObject *module, PyObject *arg);

// neighbors.c

/// find_neighbors(where, data, format, (px, py, pz), cutoff, metric, want_distances, pairs_only,
/// backend, threads) -> (pairs, distances or None): bpx_find_neighbors over a float32 or float64
/// buffer; pairs a bytearray of bpx_pair rows when pairs_only, else a tuple of bytearrays
/// (i, j, shifts); distances a bytearray of doubles.
PyObject *py_find_neighbors(PyObject *module, PyObject *args);

// query.c

/// World.query(kind, closest, any, params, categories, masks, batch) and World.query_stats().
PyObject *World_query(WorldObject *self, PyObject *args);
PyObject *World_query_stats(WorldObject *self, PyObject *unused);
/// Adds the QUERY_* kinds to the module; -1 on failure.
int add_query_constants(PyObject *module);
/// "World.query_box" and the like, for a kind (batch: "..._batch").
const char *query_name(int kind, int batch);
/// One query of a kind from Python's buffers (one row of floats, one category, one mask);
/// -1 with an exception raised.
int one_query(const char *where, int kind, int closest, int any, PyObject *params,
              PyObject *category, PyObject *mask, bpx_query *query);
/// (ids as uint32 bytes, fractions as float32 bytes or None for kinds without fractions).
PyObject *hits_result(const bpx_hit *hits, size_t count, int kind);
/// Raises a query's error; a single query's message drops bpx's "query 0: ".
PyObject *raise_query_error(const char *where, const bpx_error *error, int batch);

// prepared.c: the prepared world's queries (bpx_world_prepare_queries, bpx_world_query_shared,
// bpx_world_query_each)

PyObject *World_prepare_queries(WorldObject *self, PyObject *unused);
/// query_shared(kind, closest, any, params, category, mask) -> (ids, fractions or None)
PyObject *World_query_shared(WorldObject *self, PyObject *args);
/// query_each(kind, params, category, mask, fn, shared) -> None
PyObject *World_query_each(WorldObject *self, PyObject *args);
