/* core/'s landmark frames read as a stream (landmark_frames.c over
 * json_pull.c): the same frames as jansson's tree and the value checks
 * give, in every accepted form and across every chunk boundary of a file;
 * one line naming file:line:column for each hostile input; memory bounded
 * by the frames, not the text; frames handed out as they are read. */
#include "frames_reference.h"
#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

static const char *lm16 = "[[0,1.6,0],[0,1.3,0],[0,1,0],[0.2,1.4,0],[-0.2,1.4,0],[0.45,1.4,0],[-0.45,1.4,0],"
                          "[0.7,1.4,0],[-0.7,1.4,0],[0.1,0.95,0],[-0.1,0.95,0],[0.1,0.5,0.02],[-0.1,0.5,0.02],"
                          "[0.1,0.08,0],[-0.1,0.08,0],[0,1.15,-0.05]]";
static const char *lm4 = "[[0,0,0],[1,0,0],[0,1,0],[0,0,1.5]]";

static void assert_same_frames(const mim_landmark_frames_t *a, const mim_landmark_frames_t *b)
{
    if (!frames_equal(a, b)) fail_msg("the frames differ (%u and %u frames)", a->n_frames, b->n_frames);
}

/* Every accepted form, from memory and from a file, against the reference. */
static void test_forms_match_reference(void **s)
{
    (void)s;
    char *dir = ts_tempdir("forms"), *path = ts_path(dir, "f.json");
    static char text[8][4096];
    struct {
        uint32_t n, max_missing;
    } arg[8];
    int k = 0;
    /* one frame, nulls, numbers of every form, other members of every kind */
    arg[k].n = 4, arg[k].max_missing = 3;
    snprintf(text[k++], 4096, "{\"t\": 5, \"landmarks\": [[-0, 1e-400, 0.5E1], null, [0.25, 1, -2e-1], [1E0, 3, 1.2345678901]],"
                              " \"note\": \"caf\\u00e9 \\ud83d\\ude00 \xc3\xa9 \\\" \\\\ \\/ \\b\\f\\n\\r\\t\", \"x\": {\"y\": [true, false, null, {}, []]}}");
    /* one frame, its orientations before its landmarks, a key written with escapes */
    arg[k].n = 4, arg[k].max_missing = 0;
    snprintf(text[k++], 4096, "\n\t{ \"orientations\" : {\"pelvis\": [0, 0.6, 0, 0.8], \"head\": null},\r\n \"land\\u006darks\": %s }\n ", lm4);
    /* a batch: orientations in some frames, other members, whitespace */
    arg[k].n = 4, arg[k].max_missing = 1;
    snprintf(text[k++], 4096,
             "{\"meta\": [1, 2, {\"a\": \"b\"}], \"frames\": [{\"landmarks\": %s},{\"t\":1,\"landmarks\":[[0,0,0],null,[0,1,0],[0,0,1]],"
             "\"orientations\":{\"l_hand\":[1,0,0,0],\"r_foot\":null}} , {\"orientations\": {}, \"landmarks\": %s}], \"z\": null}",
             lm4, lm4);
    /* a batch whose first orientations come late */
    arg[k].n = 16, arg[k].max_missing = 3;
    snprintf(text[k++], 4096, "{\"frames\": [{\"landmarks\": %s}, {\"landmarks\": %s}, {\"landmarks\": %s, \"orientations\": {\"chest\": [0, 0, 0, -1]}}]}",
             lm16, lm16, lm16);
    for (int i = 0; i < k; i++) {
        mim_landmark_frames_t ref, a, b;
        mim_error_t e = {0};
        assert_int_equal(frames_reference(text[i], arg[i].n, arg[i].max_missing, &ref), 0);
        if (mim_landmark_frames_parse(text[i], strlen(text[i]), "mem", arg[i].n, arg[i].max_missing, &a, &e))
            fail_msg("form %d: %s", i, e.msg);
        assert_same_frames(&a, &ref);
        assert_int_equal(ts_write_file(path, text[i], strlen(text[i])), 0);
        assert_int_equal(mim_landmark_frames_read(path, arg[i].n, arg[i].max_missing, &b, &e), 0);
        assert_same_frames(&b, &ref);
        mim_landmark_frames_free(&ref), mim_landmark_frames_free(&a), mim_landmark_frames_free(&b);
    }
    ts_rmtree(dir);
    free(path), free(dir);
}

/* A file is read 64 KiB at a time: with the boundary at every byte of a
 * frame that has every kind of token, the frames are those of the text in
 * memory (and of the reference). */
static void test_chunk_boundaries(void **s)
{
    (void)s;
    char frame[2048];
    int flen = snprintf(frame, sizeof frame,
                        "{\"t\": 12, \"x\": {\"s\": \"caf\\u00e9 \\ud83d\\ude00 \xc3\xa9 \xf0\x9f\x98\x80 \\\" \\\\ \\/ \\b\\f\\n\\r\\t\","
                        " \"n\": [true, false, null, -0.5e-3, 1E+2, {}, []]}, \"land\\u006darks\": [[0,1.6,0],[0,1.3e0,0],"
                        "[0,1,0],[0.2,1.4,0],[-0.2,1.4,0],[0.45,1.4,0],[-0.45,1.4,0],[0.7,1.4,0],[-0.7,1.4,0],[0.1,0.95,0],"
                        "[-0.1,0.95,0],[0.1,0.5,2E-2],[-0.1,0.5,0.02],[0.1,0.08,0],null,[0,1.15,-0.05]],\n \"orientations\":"
                        " {\"head\": [0, 0, 0, 1], \"l_hand\": null, \"pelvis\": [0, 0.6, 0, 0.8]}}");
    const size_t chunk = 1 << 16;
    size_t nf = chunk / (size_t)flen + 2, size = (size_t)flen * 2 + 64 + nf * ((size_t)flen + 2);
    char *text = malloc(size);
    char *dir = ts_tempdir("chunks"), *path = ts_path(dir, "f.json");
    mim_landmark_frames_t ref = {0};
    for (int pad = 0; pad <= flen + 1; pad++) {
        size_t k = (size_t)snprintf(text, size, "%*s{\"frames\": [", pad, "");
        for (size_t i = 0; i < nf; i++) k += (size_t)snprintf(text + k, size - k, "%s%s", i ? ",\n" : "", frame);
        k += (size_t)snprintf(text + k, size - k, "]}\n");
        assert_true(k > chunk + (size_t)flen);
        mim_landmark_frames_t a, b;
        mim_error_t e = {0};
        if (!pad) assert_int_equal(frames_reference(text, 16, 3, &ref), 0);
        if (mim_landmark_frames_parse(text, k, "mem", 16, 3, &a, &e)) fail_msg("pad %d: %s", pad, e.msg);
        assert_int_equal(ts_write_file(path, text, k), 0);
        if (mim_landmark_frames_read(path, 16, 3, &b, &e)) fail_msg("pad %d: %s", pad, e.msg);
        assert_same_frames(&a, &ref);
        assert_same_frames(&b, &ref);
        mim_landmark_frames_free(&a), mim_landmark_frames_free(&b);
    }
    mim_landmark_frames_free(&ref);
    ts_rmtree(dir);
    free(text), free(path), free(dir);
}

/* The error is one line that begins with the origin. */
static void assert_one_line(const mim_error_t *e, const char *origin)
{
    assert_true(e->code != 0);
    if (strncmp(e->msg, origin, strlen(origin)) || strchr(e->msg, '\n') || strchr(e->msg, '\r'))
        fail_msg("not one line naming %s: '%s'", origin, e->msg);
}

/* Writes text of `size` bytes: head, then `fill` repeated, then tail. */
static void write_filled(const char *path, const char *head, char fill, size_t size, const char *tail)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    static char block[1 << 16];
    memset(block, fill, sizeof block);
    size_t body = size - strlen(head) - strlen(tail);
    fputs(head, f);
    for (size_t done = 0; done < body; done += sizeof block)
        fwrite(block, 1, body - done < sizeof block ? body - done : sizeof block, f);
    fputs(tail, f);
    assert_int_equal(fclose(f), 0);
}

/* Hostile input: each one line naming the file, line and column (or the
 * frame), never a crash; a big one is refused where its fault is, without
 * reading on. */
static void test_hostile(void **s)
{
    (void)s;
    char lm[128];
    snprintf(lm, sizeof lm, "\"landmarks\": %s", lm4);
    static const struct {
        const char *text;
        int code;
        const char *msg;
    } bad[] = {
        {"", MIM_EFORMAT, "h.json:1:1: expected an object with \"frames\" or \"landmarks\", found the end of the input"},
        {"  \n ", MIM_EFORMAT, "h.json:2:2: expected an object with \"frames\" or \"landmarks\", found the end of the input"},
        {"[{\"landmarks\": []}]", MIM_EFORMAT, "h.json:1:1: expected an object with \"frames\" or \"landmarks\", found '['"},
        {"{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,1e999]]}", MIM_EFORMAT, "h.json:1:45: number 1e999 is too large for a double"},
        {"{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,-1E+999]]}", MIM_EFORMAT, "h.json:1:45: number -1E+999 is too large for a double"},
        {"{\"t\": 99999999999999999999, \"landmarks\": []}", MIM_EFORMAT, "h.json:1:7: integer 99999999999999999999 does not fit 64 bits"},
        {"{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,1e300]]}", MIM_ENONFINITE, "h.json: frame 0, landmark 3: z = 1e+300 is not a finite float"},
        {"{\"landmarks\": [[NaN,0,0]]}", MIM_EFORMAT, "h.json:1:17: expected a value, found 'N'"},
        {"{\"landmarks\": [[nan,0,0]]}", MIM_EFORMAT, "h.json:1:17: invalid literal (null, true or false)"},
        {"{\"landmarks\": [[-Infinity,0,0]]}", MIM_EFORMAT, "h.json:1:17: invalid number"},
        {"{\"landmarks\": [[01,0,0]]}", MIM_EFORMAT, "h.json:1:17: invalid number: a leading zero"},
        {"{\"landmarks\": [[1.,0,0]]}", MIM_EFORMAT, "h.json:1:17: invalid number: no digit after '.'"},
        {"{\"landmarks\": [[1,0,0],]}", MIM_EFORMAT, "h.json:1:24: expected a value, found ']'"},
        {"{\"landmarks\": [[1,0,0] [0,0,0]]}", MIM_EFORMAT, "h.json:1:24: expected ',' or ']', found '['"},
        {"{\"x\": [], }", MIM_EFORMAT, "h.json:1:11: expected a member name in double quotes, found '}'"},
        {"{\"x\" [], }", MIM_EFORMAT, "h.json:1:6: expected ':', found '['"},
        {"{\"x\": \"a\x01\"}", MIM_EFORMAT, "h.json:1:9: control character 0x01 in a string"},
        {"{\"x\": \"a\\q\"}", MIM_EFORMAT, "h.json:1:9: invalid escape in a string"},
        {"{\"x\": \"\\u12\"}", MIM_EFORMAT, "h.json:1:12: \\u must be followed by four hex digits"},
        {"{\"x\": \"\\u0000\"}", MIM_EFORMAT, "h.json:1:8: \\u0000 is not allowed in a string"},
        {"{\"x\": \"\\ud800 \"}", MIM_EFORMAT, "h.json:1:8: \\uD800 is half of a surrogate pair without its second half"},
        {"{\"x\": \"\\udc00\"}", MIM_EFORMAT, "h.json:1:8: \\uDC00 is half of a surrogate pair without its first half"},
        {"{\"x\": \"\xc0\xaf\"}", MIM_EFORMAT, "h.json:1:8: invalid UTF-8 byte 0xc0"},
        {"{\"x\": \"\xed\xa0\x80\"}", MIM_EFORMAT, "h.json:1:9: invalid UTF-8 byte 0xa0"},
        {"{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,1]]} {}", MIM_EFORMAT, "h.json:1:50: only white space may follow the JSON value, found '{'"},
        {"{\"frames\": [{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,1]]}], \"frames\": []}", MIM_EFORMAT,
         "h.json:1:64: duplicate member \"frames\""},
        {"{\"frames\": []}", MIM_EFORMAT, "h.json: \"frames\" must be a non-empty array"},
        {"{\"frames\": [5]}", MIM_EFORMAT, "h.json: frame 0 is not an object with \"landmarks\""},
        {"{}", MIM_EFORMAT, "h.json: no \"frames\" or \"landmarks\" member"},
    };
    char *dir = ts_tempdir("hostile"), *path = ts_path(dir, "h.json");
    int failures = 0;
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        mim_landmark_frames_t f;
        mim_error_t e = {0};
        assert_int_equal(ts_write_file(path, bad[i].text, strlen(bad[i].text)), 0);
        int rc = mim_landmark_frames_read(path, 4, 3, &f, &e);
        if (rc != bad[i].code || !strstr(e.msg, "h.json") || strcmp(strstr(e.msg, "h.json"), bad[i].msg))
            print_error("case %zu: %d '%s'\n", i, rc, e.msg), failures++;
        assert_null(f.positions);
        /* the same from memory */
        mim_error_t m = {0};
        assert_int_equal(mim_landmark_frames_parse(bad[i].text, strlen(bad[i].text), path, 4, 3, &f, &m), rc);
        assert_string_equal(m.msg, e.msg);
    }
    assert_int_equal(failures, 0);

    /* a batch cut at every byte: one line each (an empty cut names line 1) */
    char text[2048];
    int len = snprintf(text, sizeof text,
                       "{\"frames\": [{\"t\": \"\\u00e9\xc3\xa9\", %s, \"orientations\": {\"head\": [0, 0, 0, 1]}},\n"
                       " {\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,-1.5e0]], \"x\": [true, false, null]}]}",
                       lm);
    mim_landmark_frames_t f;
    mim_error_t e = {0};
    assert_int_equal(mim_landmark_frames_parse(text, (size_t)len, "cut.json", 4, 3, &f, &e), 0);
    mim_landmark_frames_free(&f);
    for (int cut = 0; cut < len; cut++) {
        e = (mim_error_t){0};
        if (mim_landmark_frames_parse(text, (size_t)cut, "cut.json", 4, 3, &f, &e) == 0)
            fail_msg("accepted the first %d bytes", cut);
        assert_one_line(&e, "cut.json:");
    }

    /* deep nesting in a member that is not read: refused at the limit */
    char *deep = malloc(1 << 20);
    memset(deep, '[', 1 << 20);
    memcpy(deep, "{\"x\": ", 6);
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(deep, 1 << 20, "deep.json", 4, 3, &f, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "deep.json:1:2054: more than 2048 levels of nesting");
    free(deep);
    /* 64 MiB of '[' (the cap): refused at its first byte */
    write_filled(path, "", '[', MIM_LANDMARK_FRAMES_MAX_BYTES, "");
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_read(path, 4, 3, &f, &e), MIM_EFORMAT);
    assert_string_equal(strstr(e.msg, "h.json"), "h.json:1:1: expected an object with \"frames\" or \"landmarks\", found '['");
    /* ... and inside "frames": at the nesting limit, not at the end */
    write_filled(path, "{\"frames\": ", '[', MIM_LANDMARK_FRAMES_MAX_BYTES, "");
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_read(path, 4, 3, &f, &e), MIM_EFORMAT);
    assert_string_equal(strstr(e.msg, "h.json"), "h.json:1:2059: more than 2048 levels of nesting");
    /* a string of 60 MiB, and a member name of 1 MiB, where they are ignored: valid */
    char head[1024];
    snprintf(head, sizeof head, "{%s, \"note\": \"", lm);
    write_filled(path, head, 'a', 60 << 20, "\"}");
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_read(path, 4, 3, &f, &e), 0);
    assert_int_equal(f.n_frames, 1);
    mim_landmark_frames_free(&f);
    char tail[1024];
    snprintf(tail, sizeof tail, "\": 1, %s}", lm);
    write_filled(path, "{\"", 'k', 1 << 20, tail);
    assert_int_equal(mim_landmark_frames_read(path, 4, 3, &f, &e), 0);
    mim_landmark_frames_free(&f);
    /* a number of 600 digits */
    write_filled(path, "{\"landmarks\": [[0.", '1', 620, "]]}");
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_read(path, 4, 3, &f, &e), MIM_EFORMAT);
    assert_string_equal(strstr(e.msg, "h.json"), "h.json:1:17: a number of more than 512 characters");
    ts_rmtree(dir);
    free(path), free(dir);
}

typedef struct seen_frames {
    uint32_t n, with_orient, stop_at;
} seen_frames_t;

static int count_frame(void *user, const mim_landmark_frame_t *f, mim_error_t *err)
{
    seen_frames_t *s = user;
    assert_int_equal(f->index, s->n);
    s->n++;
    s->with_orient += f->orientations != NULL;
    if (f->orientations) assert_non_null(f->orient_present);
    if (f->index == s->stop_at) return mim_error_set(err, MIM_EINVAL, "stopped at frame %u", f->index);
    return 0;
}

/* Frames are handed out as they are read: a caller that stops at the first
 * never hears of the malformed text after it. */
static void test_scan_hands_out_frames(void **s)
{
    (void)s;
    char text[2048];
    snprintf(text, sizeof text,
             "{\"frames\": [{\"landmarks\": %s}, {\"landmarks\": %s, \"orientations\": {\"head\": null}}, {\"landmarks\": %s}, oops",
             lm4, lm4, lm4);
    seen_frames_t seen = {.stop_at = 0};
    mim_error_t e = {0};
    assert_int_equal(mim_landmark_frames_scan(text, strlen(text), "s.json", 4, 0, count_frame, &seen, &e), MIM_EINVAL);
    assert_string_equal(e.msg, "stopped at frame 0");
    assert_int_equal(seen.n, 1);
    /* read on: three frames, one with orientations, then the fault */
    seen = (seen_frames_t){.stop_at = UINT32_MAX};
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_scan(text, strlen(text), "s.json", 4, 0, count_frame, &seen, &e), MIM_EFORMAT);
    assert_int_equal(seen.n, 3);
    assert_int_equal(seen.with_orient, 1);
    char msg[64];
    snprintf(msg, sizeof msg, "s.json:1:%d: expected a value, found 'o'", (int)(strstr(text, "oops") - text) + 1);
    assert_string_equal(e.msg, msg);
}

/* A batch of about 20 MiB is read in memory bounded by its frames (13
 * bytes a landmark), not by its text: a tree of it took 13 times the
 * text. Measured in a child process: its peak resident size after reading
 * less at the start. */
static void test_memory_bounded(void **s)
{
    (void)s;
    char *dir = ts_tempdir("mem"), *path = ts_path(dir, "batch.json");
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    static const float body[48] = {0, 1.6f, 0, 0, 1.3f, 0, 0, 1, 0, 0.2f, 1.4f, 0, -0.2f, 1.4f, 0, 0.45f, 1.4f, 0,
                                   -0.45f, 1.4f, 0, 0.7f, 1.4f, 0, -0.7f, 1.4f, 0, 0.1f, 0.95f, 0, -0.1f, 0.95f, 0,
                                   0.1f, 0.5f, 0.02f, -0.1f, 0.5f, 0.02f, 0.1f, 0.08f, 0, -0.1f, 0.08f, 0, 0, 1.15f, -0.05f};
    long bytes = fprintf(fp, "{\"frames\": [\n");
    uint32_t nf = 0;
    mim_rng_t r;
    mim_rng_seed(&r, 7, 0);
    while (bytes < (20l << 20)) {
        bytes += fprintf(fp, "%s{\"landmarks\": [", nf ? ",\n" : "");
        for (int l = 0; l < 16; l++)
            bytes += fprintf(fp, "%s[%.9g, %.9g, %.9g]", l ? ", " : "", body[3 * l] + 0.01 * mim_rng_unit(&r),
                             body[3 * l + 1] + 0.01 * mim_rng_unit(&r), body[3 * l + 2] + 0.01 * mim_rng_unit(&r));
        bytes += fprintf(fp, "]}");
        nf++;
    }
    fprintf(fp, "\n]}\n");
    assert_int_equal(fclose(fp), 0);
    int pipefd[2];
    assert_int_equal(pipe(pipefd), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        struct rusage r0, r1;
        getrusage(RUSAGE_SELF, &r0);
        mim_landmark_frames_t f;
        int rc = mim_landmark_frames_read(path, 16, 3, &f, NULL);
        getrusage(RUSAGE_SELF, &r1);
        long out[3] = {rc, (long)f.n_frames, r1.ru_maxrss - r0.ru_maxrss};
        ssize_t w = write(pipefd[1], out, sizeof out);
        _exit(w == sizeof out ? 0 : 1);
    }
    long got[3] = {0};
    assert_int_equal(read(pipefd[0], got, sizeof got), sizeof got);
    int status;
    waitpid(pid, &status, 0);
    close(pipefd[0]), close(pipefd[1]);
    assert_int_equal(got[0], 0);
    assert_int_equal(got[1], nf);
    double frames_kib = (double)nf * 16 * 13 / 1024, text_kib = (double)bytes / 1024;
    print_message("%u frames, %.0f KiB of text, %.0f KiB of frames: the peak grew by %ld KiB\n", nf, text_kib,
                  frames_kib, got[2]);
    if ((double)got[2] > 3 * frames_kib)
        fail_msg("reading %.0f KiB took %ld KiB, more than 3 times its frames' %.0f KiB", text_kib, got[2], frames_kib);
    ts_rmtree(dir);
    free(path), free(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_forms_match_reference),
        cmocka_unit_test(test_chunk_boundaries),
        cmocka_unit_test(test_hostile),
        cmocka_unit_test(test_scan_hands_out_frames),
        cmocka_unit_test(test_memory_bounded),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
