// Internal logging through the user's bpx_set_logger hook (silent by default).
#pragma once

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
void bpx__log(int level, const char *format, ...);
