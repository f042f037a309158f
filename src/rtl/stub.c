// The rtl backend in a build without Verilator (or with -DBPX_RTL_BACKEND=OFF): it exists, and
// says why it cannot run.
#include "core/backend.h"

static bool rtl_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    (void)def;
    (void)size;
    detail[0] = '\0';
    *reason = "built without Verilator";
    return false;
}

static bpx_status rtl_compare(void **state, bpx_cycle *cycle)
{
    (void)state;
    (void)cycle;
    return BPX_ERR_BACKEND_UNAVAILABLE; // never called: no world is made with it
}

static void rtl_destroy(void *state)
{
    (void)state;
}

const bpx_backend_impl bpx__rtl_backend = {
    .id = BPX_BACKEND_RTL,
    .name = "rtl",
    .query = rtl_query,
    .compare = rtl_compare,
    .destroy = rtl_destroy,
};
