/* SPDX-License-Identifier: MIT */
/* The benchmark harnesses' one way to read their input stream: the whole file into memory (the
 * caller frees it). Returns NULL after saying why on stderr. */
#ifndef CTRLBUS_BENCH_READ_FILE_H
#define CTRLBUS_BENCH_READ_FILE_H

#include <stdio.h>
#include <stdlib.h>

static unsigned char *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        perror(path);
        return NULL;
    }
    if (fseek(f, 0, SEEK_END) != 0) {
        fclose(f);
        return NULL;
    }
    long end = ftell(f);
    rewind(f);
    unsigned char *data = malloc(end > 0 ? (size_t)end : 1u);
    if (data == NULL || fread(data, 1, (size_t)end, f) != (size_t)end) {
        fprintf(stderr, "%s: cannot read\n", path);
        free(data);
        fclose(f);
        return NULL;
    }
    fclose(f);
    *size = (size_t)end;
    return data;
}

#endif
