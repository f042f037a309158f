// bpx for Python: who may use a world when. SPDX-License-Identifier: MIT
//
// A bpx_world serves one call at a time (bpx.h), except the queries of a prepared world
// (bpx_world_query_shared, bpx_world_query_each), which read it only and may run on any number
// of threads at once while nothing changes it (query.h, "Threads"). So each World has
//   lock     taken by every call for as long as it runs (world_enter .. world_leave); a second
//            thread's call waits for it, the GIL released;
//   readers  the shared queries running now, each with the GIL released. One joins by taking
//            the lock for a moment (reader_enter): it waits for a call that holds it, never for
//            another shared query;
//   drained  held while readers > 0 (taken by the first, given back by the last): a call that
//            has the lock waits on it, so it changes the world only once the shared queries
//            that started before it are done, and none starts meanwhile (they need the lock).
// A Python callback runs inside a call (the pair filter inside collide, holding the lock; a
// query_each callback inside a query that holds the lock or is a reader): a call into the same
// world from it would wait for itself, so it raises StateError instead. Callbacks are found by
// thread: the pair filter's filter_thread, and a stack of callback_frame per thread for
// query_each (nested callbacks of different worlds stack up).
#include "_bpx.h"

#if defined(_MSC_VER)
#define THREAD_LOCAL __declspec(thread)
#else
#define THREAD_LOCAL _Thread_local
#endif

static THREAD_LOCAL callback_frame *callbacks; // this thread's query_each callbacks running now

void callback_begin(callback_frame *frame, const WorldObject *world)
{
    frame->world = world;
    frame->outer = callbacks;
    callbacks = frame;
}

void callback_end(callback_frame *frame)
{
    callbacks = frame->outer;
}

// StateError when the calling thread is inside one of self's callbacks; else 0.
static int check_not_in_callback(WorldObject *self, const char *where)
{
    // From inside its own pair filter the lock is this thread's: waiting would never end.
    if (self->filter_thread && self->filter_thread == PyThread_get_thread_ident()) {
        raise_status(where, BPX_ERR_BAD_STATE, "called from the world's own pair filter");
        return -1;
    }
    for (const callback_frame *f = callbacks; f; f = f->outer)
        if (f->world == self) {
            raise_status(where, BPX_ERR_BAD_STATE,
                         "called from the world's own query callback (each=)");
            return -1;
        }
    return 0;
}

// Takes the lock, waiting with the GIL released if another thread has it; StateError once the
// world is closed (the lock not held then).
static int take_lock(WorldObject *self, const char *where)
{
    if (!self->lock) {
        raise_status(where, BPX_ERR_BAD_STATE, "the world is not initialised");
        return -1;
    }
    if (check_not_in_callback(self, where) != 0)
        return -1;
    if (!PyThread_acquire_lock(self->lock, NOWAIT_LOCK)) {
        Py_BEGIN_ALLOW_THREADS
        PyThread_acquire_lock(self->lock, WAIT_LOCK);
        Py_END_ALLOW_THREADS
    }
    if (!self->world) {
        PyThread_release_lock(self->lock);
        raise_status(where, BPX_ERR_BAD_STATE, "the world is closed");
        return -1;
    }
    return 0;
}

int world_enter(WorldObject *self, const char *where)
{
    if (take_lock(self, where) != 0)
        return -1;
    if (self->readers > 0) { // wait for the shared queries running (none can start: the lock)
        Py_BEGIN_ALLOW_THREADS
        PyThread_acquire_lock(self->drained, WAIT_LOCK);
        PyThread_release_lock(self->drained);
        Py_END_ALLOW_THREADS
    }
    return 0;
}

void world_leave(WorldObject *self)
{
    PyThread_release_lock(self->lock);
}

int reader_enter(WorldObject *self, const char *where)
{
    if (take_lock(self, where) != 0)
        return -1;
    if (!self->drained && !(self->drained = PyThread_allocate_lock())) {
        PyThread_release_lock(self->lock);
        PyErr_NoMemory();
        return -1;
    }
    // drained is free whenever readers == 0: only readers keep it, and a call waiting on it
    // has the lock, which this thread has now.
    if (self->readers++ == 0)
        PyThread_acquire_lock(self->drained, NOWAIT_LOCK);
    PyThread_release_lock(self->lock);
    return 0;
}

void reader_leave(WorldObject *self)
{
    if (--self->readers == 0)
        PyThread_release_lock(self->drained);
}

void world_access_free(WorldObject *self)
{
    if (self->lock)
        PyThread_free_lock(self->lock);
    if (self->drained)
        PyThread_free_lock(self->drained);
    self->lock = self->drained = NULL;
}
