#include <stdarg.h>
#include <stdio.h>

#include "bpx/base.h"
#include "log.h"

static bpx_log_fn *log_fn;
static void *log_user;

const char *bpx_version(void)
{
#define BPX_STR2_(x) #x
#define BPX_STR_(x) BPX_STR2_(x)
    return BPX_STR_(BPX_VERSION_MAJOR) "." BPX_STR_(BPX_VERSION_MINOR) "." BPX_STR_(
        BPX_VERSION_PATCH);
}

const char *bpx_status_string(bpx_status status)
{
    static const char *const texts[] = {
#define BPX_STATUS_TEXT_(name, text) text,
        BPX_STATUS_LIST(BPX_STATUS_TEXT_)
#undef BPX_STATUS_TEXT_
    };
    if ((unsigned)status >= BPX_STATUS_COUNT)
        return "unknown status";
    return texts[status];
}

const char *bpx_status_name(bpx_status status)
{
    static const char *const names[] = {
#define BPX_STATUS_NAME_(name, text) #name,
        BPX_STATUS_LIST(BPX_STATUS_NAME_)
#undef BPX_STATUS_NAME_
    };
    if ((unsigned)status >= BPX_STATUS_COUNT)
        return "BPX_STATUS_UNKNOWN";
    return names[status];
}

void bpx_set_logger(bpx_log_fn *log, void *user)
{
    log_fn = log;
    log_user = user;
}

void bpx__log(int level, const char *format, ...)
{
    if (!log_fn)
        return;
    char message[512];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    log_fn(level, message, log_user);
}
