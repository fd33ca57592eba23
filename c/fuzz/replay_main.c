/* SPDX-License-Identifier: MIT */
/* main() for the fuzz targets built without libFuzzer: runs LLVMFuzzerTestOneInput() on saved
 * inputs, so that seeds and reproducers of crashes run as ordinary tests.
 *
 *   replay_<target> PATH...     each PATH a file, or a directory whose files are all run
 *
 * Exit status 0 when every input ran (a broken invariant aborts the program), 2 when a path cannot
 * be read or no input was found. */
#define _POSIX_C_SOURCE 200809L

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fuzz_common.h"

static int run_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        perror(path);
        return -1;
    }
    size_t cap = 4096;
    size_t len = 0;
    uint8_t *data = malloc(cap);
    while (data != NULL) {
        size_t got = fread(data + len, 1, cap - len, f);
        len += got;
        if (got == 0) {
            break;
        }
        if (len == cap) {
            cap *= 2;
            uint8_t *bigger = realloc(data, cap);
            if (bigger == NULL) {
                free(data);
            }
            data = bigger;
        }
    }
    int failed = ferror(f) || data == NULL;
    fclose(f);
    if (failed) {
        fprintf(stderr, "%s: cannot read\n", path);
        free(data);
        return -1;
    }
    (void)LLVMFuzzerTestOneInput(data, len);
    free(data);
    return 1;
}

/* Runs path (a file, or every file of a directory, sorted). Returns the inputs run, or -1. */
static int run_path(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        perror(path);
        return -1;
    }
    if (!S_ISDIR(st.st_mode)) {
        return run_file(path);
    }
    struct dirent **names = NULL;
    int n = scandir(path, &names, NULL, alphasort);
    if (n < 0) {
        perror(path);
        return -1;
    }
    int ran = 0;
    for (int i = 0; i < n; i++) {
        if (names[i]->d_name[0] != '.' && ran >= 0) {
            size_t need = strlen(path) + strlen(names[i]->d_name) + 2u;
            char *file = malloc(need);
            if (file == NULL) {
                ran = -1;
            } else {
                snprintf(file, need, "%s/%s", path, names[i]->d_name);
                int result = run_file(file);
                ran = result < 0 ? -1 : ran + result;
                free(file);
            }
        }
        free(names[i]);
    }
    free(names);
    return ran;
}

int main(int argc, char **argv)
{
    int total = 0;
    for (int i = 1; i < argc; i++) {
        int ran = run_path(argv[i]);
        if (ran < 0) {
            return 2;
        }
        total += ran;
    }
    if (total == 0) {
        fprintf(stderr, "%s: no inputs to run\n", argv[0]);
        return 2;
    }
    printf("%s: %d inputs, no invariant broken\n", argv[0], total);
    return 0;
}
