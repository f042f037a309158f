// Runs a harness's LLVMFuzzerTestOneInput once on each file named (a folder: on each file in
// it, in name order), so that seed corpora and crash inputs replay under any C compiler: the
// release, asan and tsan builds run fuzz/corpus/ and fuzz/regressions/ through this driver.
// SPDX-License-Identifier: MIT
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int replay_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "replay: cannot open %s\n", path);
        return 1;
    }
    size_t capacity = 4096, size = 0;
    uint8_t *data = malloc(capacity);
    for (;;) {
        if (!data) {
            fclose(f);
            fprintf(stderr, "replay: out of memory reading %s\n", path);
            return 1;
        }
        size += fread(data + size, 1, capacity - size, f);
        if (size < capacity)
            break;
        uint8_t *grown = realloc(data, capacity * 2);
        if (!grown)
            free(data);
        data = grown;
        capacity *= 2;
    }
    int failed = ferror(f);
    fclose(f);
    if (failed) {
        free(data);
        fprintf(stderr, "replay: read error on %s\n", path);
        return 1;
    }
    // A copy of exactly the input's size, so ASan sees a read past its end.
    uint8_t *exact = malloc(size ? size : 1);
    if (exact && size)
        memcpy(exact, data, size);
    free(data);
    if (!exact)
        return 1;
    LLVMFuzzerTestOneInput(exact, size);
    free(exact);
    return 0;
}

static int by_name(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

static int replay_dir(const char *path, int *count)
{
    DIR *dir = opendir(path);
    if (!dir) {
        fprintf(stderr, "replay: cannot open folder %s\n", path);
        return 1;
    }
    char **names = NULL;
    size_t n = 0, capacity = 0;
    int status = 0;
    struct dirent *entry;
    while ((entry = readdir(dir)) != NULL) {
        if (entry->d_name[0] == '.')
            continue;
        if (n == capacity) {
            capacity = capacity ? 2 * capacity : 64;
            char **grown = realloc(names, capacity * sizeof *names);
            if (!grown) {
                status = 1;
                break;
            }
            names = grown;
        }
        size_t length = strlen(path) + strlen(entry->d_name) + 2;
        names[n] = malloc(length);
        if (!names[n]) {
            status = 1;
            break;
        }
        snprintf(names[n], length, "%s/%s", path, entry->d_name);
        n++;
    }
    closedir(dir);
    if (n)
        qsort(names, n, sizeof *names, by_name);
    for (size_t k = 0; k < n; k++) {
        if (status == 0) {
            status = replay_file(names[k]);
            ++*count;
        }
        free(names[k]);
    }
    free(names);
    return status;
}

int main(int argc, char **argv)
{
    int count = 0;
    for (int a = 1; a < argc; a++) {
        struct stat st;
        if (stat(argv[a], &st) != 0) {
            fprintf(stderr, "replay: no such file or folder: %s\n", argv[a]);
            return 1;
        }
        int status = S_ISDIR(st.st_mode) ? replay_dir(argv[a], &count)
                                         : (count++, replay_file(argv[a]));
        if (status != 0)
            return 1;
    }
    printf("replayed %d inputs\n", count);
    return 0;
}
