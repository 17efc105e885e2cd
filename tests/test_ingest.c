/* ingest/: readers on every format and every bad-file case, labels,
 * manifests, discovery, and the pipeline (bad files skipped, topology
 * mismatch, idempotency, landmark map checks). */
#include "mim_db.h"
#include "known_maps.h"
#include "mim_ingest.h"
#include "mim_register.h"
#include "mim_io.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static ts_polymesh_t sphere;
static char *dir;

static int setup(void **state)
{
    (void)state;
    ts_sphere(&sphere, 12, 16, 0.5f);
    dir = ts_tempdir("ingest");
    return dir ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    ts_polymesh_free(&sphere);
    ts_rmtree(dir);
    free(dir);
    return 0;
}

/* Reads `name` and expects exactly the fan-triangulated sphere. */
static void expect_exact(const char *name, int (*writer)(const char *, const ts_polymesh_t *))
{
    char *p = ts_path(dir, name);
    assert_int_equal(writer(p, &sphere), 0);
    mim_mesh_t m, want;
    mim_error_t err = {0};
    int rc = mim_io_read_mesh(p, &m, &err);
    if (rc) fprintf(stderr, "%s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
    ts_triangulate(&sphere, &want);
    assert_int_equal(m.n_vertices, want.n_vertices);
    assert_int_equal(m.n_faces, want.n_faces);
    assert_memory_equal(m.faces, want.faces, (size_t)m.n_faces * 12);
    for (uint32_t i = 0; i < 3 * m.n_vertices; i++) assert_true(fabsf(m.positions[i] - want.positions[i]) < 1e-6f);
    mim_mesh_free(&m);
    mim_mesh_free(&want);
    free(p);
}

static void test_read_off(void **s) { (void)s; expect_exact("s.off", ts_write_off); }
static void test_read_ply_ascii(void **s) { (void)s; expect_exact("sa.ply", ts_write_ply_ascii); }
static void test_read_ply_binary(void **s) { (void)s; expect_exact("sb.ply", ts_write_ply_binary); }
static void test_read_obj(void **s) { (void)s; expect_exact("s.obj", ts_write_obj); }
static void test_read_glb(void **s) { (void)s; expect_exact("s.glb", ts_write_glb); }
static void test_read_gltf(void **s) { (void)s; expect_exact("s.gltf", ts_write_gltf); }

/* STL stores triangle soup: vertices are merged by position, so compare
 * each triangle's corner positions. */
static void expect_stl(const char *name, int (*writer)(const char *, const ts_polymesh_t *))
{
    char *p = ts_path(dir, name);
    assert_int_equal(writer(p, &sphere), 0);
    mim_mesh_t m, want;
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_mesh(p, &m, &err), 0);
    ts_triangulate(&sphere, &want);
    assert_int_equal(m.n_faces, want.n_faces);
    assert_int_equal(m.n_vertices, want.n_vertices); /* shared corners merged back */
    for (uint32_t t = 0; t < m.n_faces; t++)
        for (int c = 0; c < 3; c++)
            for (int a = 0; a < 3; a++)
                assert_true(fabsf(m.positions[3 * m.faces[3 * t + c] + a] - want.positions[3 * want.faces[3 * t + c] + a]) < 1e-6f);
    mim_mesh_free(&m);
    mim_mesh_free(&want);
    free(p);
}
static void test_read_stl_ascii(void **s) { (void)s; expect_stl("sa.stl", ts_write_stl_ascii); }
static void test_read_stl_binary(void **s) { (void)s; expect_stl("sb.stl", ts_write_stl_binary); }

/* Expects mim_io_read_mesh to fail with `code` and a message naming the file and `phrase`. */
static void expect_error(const char *path, int code, const char *phrase)
{
    mim_mesh_t m;
    mim_error_t err = {0};
    int rc = mim_io_read_mesh(path, &m, &err);
    if (rc != code || !strstr(err.msg, path) || !strstr(err.msg, phrase))
        fprintf(stderr, "file %s: rc %d (%s), message: %s\n", path, rc, mim_strerror(rc), err.msg);
    assert_int_equal(rc, code);
    assert_non_null(strstr(err.msg, path));
    assert_non_null(strstr(err.msg, phrase));
    assert_null(strchr(err.msg, '\n'));
    assert_int_equal(m.n_vertices, 0);
    assert_null(m.positions);
}

static void cut_at(const char *path, double fraction)
{
    size_t len;
    char *b = ts_read_file(path, &len);
    free(b);
    assert_int_equal(ts_truncate(path, (size_t)(len * fraction)), 0);
}

static void test_truncated(void **s)
{
    (void)s;
    struct { const char *name; int (*w)(const char *, const ts_polymesh_t *); } cases[] = {
        {"t_bin.ply", ts_write_ply_binary}, {"t_ascii.ply", ts_write_ply_ascii}, {"t.off", ts_write_off},
        {"t_bin.stl", ts_write_stl_binary}, {"t_ascii.stl", ts_write_stl_ascii}, {"t.glb", ts_write_glb},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        for (double frac = 0.3; frac < 0.95; frac += 0.3) {
            char *p = ts_path(dir, cases[i].name);
            assert_int_equal(cases[i].w(p, &sphere), 0);
            cut_at(p, frac);
            expect_error(p, MIM_ETRUNCATED, "truncated");
            free(p);
        }
    /* a PLY cut inside its header */
    char *p = ts_path(dir, "t_header.ply");
    ts_write_ply_binary(p, &sphere);
    ts_truncate(p, 60);
    expect_error(p, MIM_ETRUNCATED, "end_header");
    free(p);
    /* an OBJ that stops in the middle of a face line */
    p = ts_path(dir, "t.obj");
    ts_write_obj(p, &sphere);
    size_t len;
    char *text = ts_read_file(p, &len);
    char *last_f = text;
    for (char *q = strstr(text, "\nf "); q; q = strstr(q + 1, "\nf ")) last_f = q;
    ts_truncate(p, (size_t)(last_f - text) + 5); /* "\nf 1" */
    free(text);
    expect_error(p, MIM_ETRUNCATED, "truncated");
    free(p);
}

static void test_nonfinite(void **s)
{
    (void)s;
    ts_polymesh_t bad;
    ts_sphere(&bad, 12, 16, 0.5f);
    bad.pos[3 * 7 + 1] = NAN;
    char *p = ts_path(dir, "nan_bin.ply");
    ts_write_ply_binary(p, &bad);
    expect_error(p, MIM_ENONFINITE, "vertex 7");
    free(p);
    p = ts_path(dir, "nan.glb");
    ts_write_glb(p, &bad);
    expect_error(p, MIM_ENONFINITE, "vertex 7");
    free(p);
    bad.pos[3 * 7 + 1] = INFINITY;
    p = ts_path(dir, "inf_bin.stl");
    ts_write_stl_binary(p, &bad);
    expect_error(p, MIM_ENONFINITE, "non-finite");
    free(p);
    /* text formats spell it out: the message gives the line */
    const char *text_cases[][2] = {{"nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"},
                                   {"inf.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 -inf 1\n3 0 1 2\n"},
                                   {"nan_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                                     "property float y\nproperty float z\nelement face 1\n"
                                                     "property list uchar int vertex_indices\nend_header\n"
                                                     "0 0 0\n1 0 NaN\n0 1 0\n3 0 1 2\n"}};
    const char *lines[] = {":2:", ":5:", ":11:"};
    for (int i = 0; i < 3; i++) {
        p = ts_path(dir, text_cases[i][0]);
        ts_write_file(p, text_cases[i][1], strlen(text_cases[i][1]));
        expect_error(p, MIM_ENONFINITE, lines[i]);
        free(p);
    }
    ts_polymesh_free(&bad);
}

static void test_bad_index(void **s)
{
    (void)s;
    ts_polymesh_t bad;
    ts_sphere(&bad, 12, 16, 0.5f);
    bad.idx[40] = bad.n_vertices + 5;
    char want[64];
    snprintf(want, sizeof want, "vertex %u", bad.n_vertices + 5);
    int (*writers[])(const char *, const ts_polymesh_t *) = {ts_write_ply_binary, ts_write_ply_ascii, ts_write_off,
                                                             ts_write_obj, ts_write_glb};
    const char *names[] = {"idx_bin.ply", "idx_ascii.ply", "idx.off", "idx.obj", "idx.glb"};
    for (int i = 0; i < 5; i++) {
        char *p = ts_path(dir, names[i]);
        writers[i](p, &bad);
        expect_error(p, MIM_EINDEX, want);
        free(p);
    }
    ts_polymesh_free(&bad);
}

static void test_empty(void **s)
{
    (void)s;
    const char *cases[][2] = {
        {"empty.off", "OFF\n0 0 0\n"},
        {"empty.ply", "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 0\nproperty list uchar int vertex_indices\nend_header\n"},
        {"empty.obj", "# nothing here\n"},
        {"points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"},
        {"zero.stl", ""},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char *p = ts_path(dir, cases[i][0]);
        ts_write_file(p, cases[i][1], strlen(cases[i][1]));
        expect_error(p, MIM_EEMPTY, "empty mesh");
        free(p);
    }
}

static void test_unreadable(void **s)
{
    (void)s;
    char *p = ts_path(dir, "does-not-exist.ply");
    expect_error(p, MIM_ENOTFOUND, "No such file");
    free(p);
    p = ts_path(dir, "dangling.ply");
    assert_int_equal(symlink("/nonexistent/target.ply", p), 0);
    expect_error(p, MIM_ENOTFOUND, "cannot read");
    free(p);
    p = ts_path(dir, "adir.ply");
    assert_int_equal(mkdir(p, 0755), 0);
    expect_error(p, MIM_EINVAL, "directory");
    free(p);
    p = ts_path(dir, "mesh.xyz");
    ts_write_file(p, "1 2 3\n", 6);
    expect_error(p, MIM_EUNSUPPORTED, "unknown mesh format");
    free(p);
    p = ts_path(dir, "commented.off");
    ts_write_file(p, "OFF\n# made by hand\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", 46);
    expect_error(p, MIM_EUNSUPPORTED, "comment");
    free(p);
    p = ts_path(dir, "bad_face.obj"); /* OpenMesh would assert on this one */
    ts_write_file(p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf /2 3 1\n", 34);
    expect_error(p, MIM_EFORMAT, "bad_face.obj:4: a face needs at least 3 vertex references");
    free(p);
    p = ts_path(dir, "garbage.ply");
    ts_write_file(p, "this is not a ply file at all\n", 30);
    expect_error(p, MIM_EFORMAT, "PLY");
    free(p);
}

/* Malformed files that must be stopped before the library reads them (each
 * of these crashed, hung or asserted inside OpenMesh when fuzzed). */
static void test_malformed(void **s)
{
    (void)s;
    const char *hdr = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    char big[512];
    struct { const char *name, *text; int code; const char *phrase; } cases[] = {
        {"version.ply", "ply\nformat ascii 2.0\nelement vertex 0\nend_header\n", MIM_EFORMAT, "header line 2"},
        {"keyword.ply", "ply\nformat ascii 1.0\nbogus line\nend_header\n", MIM_EFORMAT, "unknown keyword 'bogus'"},
        {"control.ply", "ply\nformat ascii 1.0\ncomment a\x01b\nend_header\n", MIM_EFORMAT, "control character"},
        {"noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n", MIM_EFORMAT,
         "x, y and z"},
        {"intcount.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                         "property float z\nelement face 1\nproperty list int int vertex_indices\nend_header\n",
         MIM_EFORMAT, "uchar or ushort"},
        {"hugeface.ply", NULL, MIM_EFORMAT, ":13: a face line needs"},
        {"shortvert.ply", NULL, MIM_EFORMAT, ":11: a vertex line needs 3 numbers"},
        {"offmagic.off", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", MIM_EFORMAT, ":1: expected the OFF keyword"},
        {"offk.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", MIM_EFORMAT, ":6: a face line needs"},
        {"offbin.off", "OFF BINARY\n", MIM_EUNSUPPORTED, "binary OFF"},
    };
    snprintf(big, sizeof big, "%s0 0 0\n1 0 0\n0 1 0\n0 999999999999999999990 1\n", hdr);
    cases[5].text = strdup(big);
    snprintf(big, sizeof big, "%s0 0 0\n1 0\n0 1 0\n3 0 1 2\n", hdr);
    cases[6].text = strdup(big);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char *p = ts_path(dir, cases[i].name);
        ts_write_file(p, cases[i].text, strlen(cases[i].text));
        expect_error(p, cases[i].code, cases[i].phrase);
        free(p);
    }
    free((char *)cases[5].text);
    free((char *)cases[6].text);
}

static void test_labels(void **s)
{
    (void)s;
    mim_labels_t l;
    assert_true(mim_labels_from_name("/data/faust/tr_reg_034.ply", &l));
    assert_string_equal(l.subject, "3");
    assert_string_equal(l.pose, "4");
    assert_true(mim_labels_from_name("scape/mesh052.ply", &l));
    assert_string_equal(l.subject, "0");
    assert_string_equal(l.pose, "52");
    assert_true(mim_labels_from_name("synth_s03_p11.ply", &l));
    assert_string_equal(l.subject, "3");
    assert_string_equal(l.pose, "11");
    assert_true(mim_labels_from_name("x/mh_s07_p00.ply", &l));
    assert_string_equal(l.subject, "7");
    assert_string_equal(l.pose, "0");
    assert_false(mim_labels_from_name("random_name.ply", &l));
    assert_string_equal(l.subject, "");
    assert_false(mim_labels_from_name("tr_reg_03.ply", &l));
    assert_false(mim_labels_from_name("mesh1234.ply", &l));
}

static void test_manifest(void **s)
{
    (void)s;
    char *mp = ts_path(dir, "manifest.csv");
    const char *csv = "pose,file,extra,subject\nsit,\"a,b.ply\",x,alice\n\"stand\",sub/c.ply,,bob\n";
    ts_write_file(mp, csv, strlen(csv));
    mim_manifest_t *m;
    mim_error_t err = {0};
    assert_int_equal(mim_manifest_load(&m, mp, &err), 0);
    mim_labels_t l;
    assert_true(mim_manifest_lookup(m, "/elsewhere/a,b.ply", &l));
    assert_string_equal(l.subject, "alice");
    assert_string_equal(l.pose, "sit");
    assert_true(mim_manifest_lookup(m, "c.ply", &l));
    assert_string_equal(l.subject, "bob");
    assert_false(mim_manifest_lookup(m, "d.ply", &l));
    mim_manifest_free(&m);
    assert_null(m);
    const char *bad = "file,subject\nx.ply,1\n";
    ts_write_file(mp, bad, strlen(bad));
    mim_error_clear(&err);
    assert_int_equal(mim_manifest_load(&m, mp, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "file, subject and pose"));
    const char *short_row = "file,subject,pose\nx.ply,1\n";
    ts_write_file(mp, short_row, strlen(short_row));
    mim_error_clear(&err);
    assert_int_equal(mim_manifest_load(&m, mp, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "manifest.csv:2"));
    free(mp);
}

/* A dataset of perturbed spheres sharing one connectivity. */
static char *make_dataset(const char *name, int n, int with_landmarks)
{
    char *d = ts_path(dir, name);
    mkdir(d, 0755);
    for (int i = 0; i < n; i++) {
        ts_polymesh_t m;
        ts_sphere(&m, 12, 16, 0.5f + 0.01f * (float)i);
        char fn[64];
        snprintf(fn, sizeof fn, "ball_s%02d_p%02d.ply", i % 3, i / 3);
        char *p = ts_path(d, fn);
        ts_write_ply_binary(p, &m);
        free(p);
        ts_polymesh_free(&m);
    }
    if (with_landmarks) {
        char *p = ts_path(d, "landmarks.json");
        const char *lm = "{\"landmarks\":[{\"name\":\"top\",\"vertex\":0},{\"name\":\"l_side\",\"vertex\":5},"
                         "{\"name\":\"r_side\",\"vertex\":13},{\"name\":\"bottom\",\"vertex\":177}]}";
        ts_write_file(p, lm, strlen(lm));
        free(p);
    }
    return d;
}

static void test_pipeline(void **s)
{
    (void)s;
    char *data = make_dataset("ds1", 9, 1);
    /* bad files beside the good ones */
    char *bad1 = ts_path(data, "zz_truncated.ply");
    ts_write_ply_binary(bad1, &sphere);
    ts_truncate(bad1, 300);
    ts_polymesh_t other;
    ts_sphere(&other, 10, 16, 0.5f);
    char *bad2 = ts_path(data, "zz_other_topology.off");
    ts_write_off(bad2, &other);
    ts_polymesh_free(&other);

    char *store = ts_path(dir, "store1");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_ingest_options_t opt = {.batch = 4, .quiet = 1};
    mim_ingest_report_t rep;
    char *paths[] = {data};
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), 0);
    assert_int_equal(rep.files, 11);
    assert_int_equal(rep.added, 9);
    assert_int_equal(rep.failed, 2);
    assert_int_equal(rep.templates, 9);

    /* labels from the NAME_sSS_pPP layout; connectivity and landmarks stored */
    mim_db_txn_t *t;
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    mim_template_view_t v;
    assert_int_equal(mim_db_template_get(t, 5, &v, &err), 0);
    assert_string_equal(v.subject, "1");
    assert_string_equal(v.pose, "1");
    assert_non_null(strstr(v.source, "ball_s01_p01.ply"));
    mim_db_topology_t topo;
    assert_int_equal(mim_db_topology_get(t, &topo, &err), 0);
    assert_int_equal(topo.n_vertices, sphere.n_vertices);
    mim_landmark_map_t lm;
    assert_int_equal(mim_db_landmarks_get(t, &lm, &err), 0);
    assert_int_equal(lm.count, 4);
    assert_int_equal(lm.mirror[1], 2); /* l_side <-> r_side paired by name */
    assert_int_equal(lm.topology_vertices, sphere.n_vertices);
    mim_db_abort(&t);

    /* idempotent: the same files again add nothing */
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), 0);
    assert_int_equal(rep.added, 0);
    assert_int_equal(rep.duplicates, 9);
    assert_int_equal(rep.templates, 9);
    /* the same content under another name is stored once */
    char *copy = ts_path(dir, "copy_of_first.ply");
    char *first = ts_path(data, "ball_s00_p00.ply");
    size_t len;
    char *bytes = ts_read_file(first, &len);
    ts_write_file(copy, bytes, len);
    char *cpaths[] = {copy};
    assert_int_equal(mim_ingest_run(db, cpaths, 1, &opt, &rep, &err), 0);
    assert_int_equal(rep.duplicates, 1);
    assert_int_equal(rep.templates, 9);
    mim_db_close(&db);
    assert_null(db);
    free(bytes), free(copy), free(first), free(store), free(bad1), free(bad2), free(data);
}

static void test_landmark_requirements(void **s)
{
    (void)s;
    char *data = make_dataset("ds_nolm", 2, 0);
    char *store = ts_path(dir, "store_nolm");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_ingest_options_t opt = {.quiet = 1};
    mim_ingest_report_t rep;
    char *paths[] = {data};
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), MIM_ENOLANDMARKS);
    assert_non_null(strstr(err.msg, "--landmarks"));
    /* a map whose vertex is past the mesh: nothing goes in */
    char *lmp = ts_path(dir, "bad_landmarks.json");
    const char *lm = "{\"landmarks\":[{\"name\":\"a\",\"vertex\":0},{\"name\":\"b\",\"vertex\":1},"
                     "{\"name\":\"c\",\"vertex\":2},{\"name\":\"d\",\"vertex\":99999}]}";
    ts_write_file(lmp, lm, strlen(lm));
    opt.landmarks_path = lmp;
    mim_error_clear(&err);
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), MIM_EINDEX);
    assert_non_null(strstr(err.msg, "99999"));
    mim_db_txn_t *t;
    mim_db_meta_t meta;
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    assert_int_equal(mim_db_meta_get(t, &meta, &err), 0);
    assert_int_equal(meta.templates, 0);
    mim_db_topology_t topo;
    assert_int_equal(mim_db_topology_get(t, &topo, &err), MIM_ENOTFOUND);
    mim_db_abort(&t);
    /* a malformed map: line and column */
    ts_write_file(lmp, "{\"landmarks\": [", 15);
    mim_error_clear(&err);
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "bad_landmarks.json:1:"));
    mim_db_close(&db);
    free(lmp), free(store), free(data);
}

static void test_discover(void **s)
{
    (void)s;
    char *d = ts_path(dir, "walk");
    mkdir(d, 0755);
    char *sub = ts_path(d, "deeper");
    mkdir(sub, 0755);
    const char *files[] = {"b.ply", "a.OBJ", "notes.txt", ".hidden.ply"};
    for (int i = 0; i < 4; i++) {
        char *p = ts_path(i == 1 ? sub : d, files[i]);
        ts_write_file(p, "x", 1);
        free(p);
    }
    char *paths[] = {d};
    mim_file_list_t l;
    mim_error_t err = {0};
    assert_int_equal(mim_discover(paths, 1, &l, &err), 0);
    assert_int_equal(l.count, 2);
    assert_non_null(strstr(l.paths[0], "walk/b.ply"));
    assert_non_null(strstr(l.paths[1], "walk/deeper/a.OBJ"));
    mim_file_list_free(&l);
    free(sub), free(d);
}

/* What the log callback heard: one entry per line, with its level. */
typedef struct {
    int n;
    int level[32];
    char msg[32][600];
} heard_t;

static void hear(void *ctx, int level, const char *msg)
{
    heard_t *h = ctx;
    if (h->n < 32) {
        h->level[h->n] = level;
        snprintf(h->msg[h->n], sizeof h->msg[0], "%s", msg);
        h->n++;
    }
}

/* Ingests folder data into a new store dir/NAME, the library's log lines
 * heard in h; the store stays open in *db for the test's checks. */
static void ingest_heard(const char *name, char *data, heard_t *h, mim_db_t **db, mim_ingest_report_t *rep)
{
    char *store = ts_path(dir, name);
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(db, store, NULL, &err), 0);
    memset(h, 0, sizeof *h);
    mim_ingest_options_t opt = {.log = hear, .log_ctx = h};
    char *paths[] = {data};
    if (mim_ingest_run(*db, paths, 1, &opt, rep, &err))
        fail_msg("ingest failed: %s", mim_error_text(&err));
    free(store);
}

/* The line that contains `phrase`, asserting there is exactly one. */
static const char *heard_line(const heard_t *h, const char *phrase)
{
    const char *found = NULL;
    for (int i = 0; i < h->n; i++)
        if (strstr(h->msg[i], phrase)) {
            if (found) fail_msg("two lines say '%s'", phrase);
            found = h->msg[i];
        }
    if (!found) {
        for (int i = 0; i < h->n; i++) fprintf(stderr, "heard: %s\n", h->msg[i]);
        fail_msg("no line says '%s'", phrase);
    }
    assert_null(strchr(found, '\n'));
    return found;
}

/* A table of known connectivities holding the test sphere's: matched by
 * register/'s own code (the faces' SHA-256 and vertex count), as the
 * built-in SMPL map is matched on FAUST scans, which cannot ship here. */
static char known_sphere_json[1024];
static int known_sphere(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices, mim_landmark_map_t *map,
                        const char **name)
{
    char hex[65];
    mim_reg_faces_sha256(faces, n_faces, hex);
    *name = "sphere-test.json";
    return mim__known_map_match(known_sphere_json, *name, hex, n_vertices, map, NULL) == 1;
}

/* Issue 30 item 1: a new store takes meshes of a known connectivity with
 * no landmark file (the map of their faces), says which map it took, and a
 * mesh of an unknown one gets a message that names every way out. */
static void test_builtin_map_first_ingest(void **s)
{
    (void)s;
    mim_mesh_t tri;
    ts_triangulate(&sphere, &tri);
    char hex[65];
    mim_reg_faces_sha256(tri.faces, tri.n_faces, hex);
    snprintf(known_sphere_json, sizeof known_sphere_json,
             "{\"topology_vertices\": %u, \"faces_sha256\": \"%s\", \"landmarks\":[{\"name\":\"top\",\"vertex\":0},"
             "{\"name\":\"l_side\",\"vertex\":5},{\"name\":\"r_side\",\"vertex\":13},{\"name\":\"bottom\",\"vertex\":177}]}",
             tri.n_vertices, hex);
    mim_mesh_free(&tri);
    char *data = make_dataset("ds_known", 3, 0);
    char *store = ts_path(dir, "store_known");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    heard_t h = {0};
    mim_ingest_options_t opt = {.log = hear, .log_ctx = &h, .known_map = known_sphere};
    mim_ingest_report_t rep;
    char *paths[] = {data};
    if (mim_ingest_run(db, paths, 1, &opt, &rep, &err)) fail_msg("%s", mim_error_text(&err));
    assert_int_equal(rep.added, 3);
    const char *note = heard_line(&h, "built-in map sphere-test.json");
    assert_non_null(strstr(note, "ball_s00_p00.ply"));
    mim_db_txn_t *t;
    mim_landmark_map_t lm;
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    assert_int_equal(mim_db_landmarks_get(t, &lm, &err), 0);
    mim_db_abort(&t);
    assert_int_equal(lm.count, 4);
    assert_int_equal(lm.vertex[3], 177);
    mim_db_close(&db);
    /* a dataset name outside the set: refused by the library, before anything is read */
    opt = (mim_ingest_options_t){.quiet = 1, .dataset = "../x"};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "dataset '../x': a name is 1 to 64 of the letters"));
    assert_int_equal(rep.added, 0);
    mim_db_close(&db);
    mim_error_clear(&err);
    /* the built-in maps do not know the sphere: the message names every way */
    char *store2 = ts_path(dir, "store_unknown");
    assert_int_equal(mim_db_open(&db, store2, NULL, &err), 0);
    opt = (mim_ingest_options_t){.quiet = 1};
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), MIM_ENOLANDMARKS);
    assert_non_null(strstr(err.msg, "--landmarks FILE"));
    assert_non_null(strstr(err.msg, "built-in map"));
    assert_non_null(strstr(err.msg, "mimic landmarks maps"));
    assert_null(strchr(err.msg, '\n'));
    mim_db_close(&db);
    free(store2), free(store), free(data);
}


/* A folder with good meshes, a loop back to itself (a -> .), a link to its
 * parent (b -> ..), a link to itself and a dangling link: the good meshes go
 * in, each odd entry is one line, loops are skipped, the dangling link is a
 * failure (exit status 1 from the command). */
static void test_symlinks(void **s)
{
    (void)s;
    char *parent = ts_path(dir, "links");
    mkdir(parent, 0755);
    char *data = ts_path(parent, "data");
    mkdir(data, 0755);
    for (int i = 0; i < 3; i++) {
        ts_polymesh_t m;
        ts_sphere(&m, 12, 16, 0.5f + 0.01f * (float)i);
        char fn[64];
        snprintf(fn, sizeof fn, "ball_s00_p%02d.ply", i);
        char *p = ts_path(data, fn);
        ts_write_ply_binary(p, &m);
        free(p);
        ts_polymesh_free(&m);
    }
    char *lm = ts_path(data, "landmarks.json");
    const char *lmt = "{\"landmarks\":[{\"name\":\"top\",\"vertex\":0},{\"name\":\"l_side\",\"vertex\":5},"
                      "{\"name\":\"r_side\",\"vertex\":13},{\"name\":\"bottom\",\"vertex\":177}]}";
    ts_write_file(lm, lmt, strlen(lmt));
    char *a = ts_path(data, "a"), *b = ts_path(data, "b"), *self = ts_path(data, "self"), *gone = ts_path(data, "gone.ply");
    assert_int_equal(symlink(".", a), 0);
    assert_int_equal(symlink("..", b), 0);
    assert_int_equal(symlink("self", self), 0);
    assert_int_equal(symlink("/nonexistent/gone.ply", gone), 0);

    mim_db_t *db;
    heard_t h;
    mim_ingest_report_t rep;
    ingest_heard("store_links", data, &h, &db, &rep);
    assert_int_equal(rep.added, 3);
    assert_int_equal(rep.templates, 3);
    assert_int_equal(rep.failed, 1);
    assert_int_equal(rep.skipped, 3);
    assert_int_equal(rep.files, 4); /* 3 meshes and the dangling link */
    assert_int_equal(h.n, 4);
    char want[4200];
    snprintf(want, sizeof want, "%s: symlink loop (already walked as %s), skipped", a, data);
    assert_string_equal(heard_line(&h, "/data/a:"), want);
    assert_non_null(strstr(heard_line(&h, "/data/b:"), "/data/b: symlink loop (to "));
    assert_non_null(strstr(heard_line(&h, "/data/b:"), "links, which holds "));
    assert_non_null(strstr(heard_line(&h, "/data/self:"), "/data/self: symlink loop (the link to self never resolves), skipped"));
    snprintf(want, sizeof want, "%s: dangling symlink to /nonexistent/gone.ply", gone);
    assert_string_equal(heard_line(&h, "gone.ply"), want);
    for (int i = 0; i < h.n; i++)
        assert_int_equal(h.level[i], strstr(h.msg[i], "dangling") ? MIM_LOG_ERROR : MIM_LOG_WARN);
    mim_db_close(&db);

    /* the command: exit status 1 (some input failed), one line each */
    char *store2 = ts_path(dir, "store_links_cli");
    const char *args[] = {"ingest", "--store", store2, data, NULL};
    char *out = NULL, *errs = NULL;
    assert_int_equal(ts_run_mimic(&out, &errs, args), 1);
    assert_non_null(strstr(out, "3 added, 0 already stored, 1 failed, 3 skipped"));
    assert_non_null(strstr(errs, "dangling symlink to /nonexistent/gone.ply\n"));
    assert_non_null(strstr(errs, "/data/a: symlink loop (already walked as "));
    free(out), free(errs);
    free(store2), free(a), free(b), free(self), free(gone), free(lm), free(data), free(parent);
}

/* A .gltf whose buffer is the triangulated sphere in an external file: the
 * .bin at bin_path, the JSON at path naming it as `uri` (JSON text: it may
 * hold escapes). Optional extra members for the root (images). */
static void write_gltf_external(const char *path, const char *uri, const char *bin_path, const char *extra)
{
    mim_mesh_t m;
    ts_triangulate(&sphere, &m);
    if (bin_path) {
        FILE *f = fopen(bin_path, "wb");
        assert_non_null(f);
        fwrite(m.positions, 12, m.n_vertices, f);
        fwrite(m.faces, 12, m.n_faces, f);
        fclose(f);
    }
    mim_mesh_free(&m);
    /* ts_write_gltf's JSON, its data: URI replaced by uri */
    char *tmp = ts_path(dir, "embedded_tmp.gltf");
    assert_int_equal(ts_write_gltf(tmp, &sphere), 0);
    size_t len;
    char *text = ts_read_file(tmp, &len);
    char *u = strstr(text, "\"uri\":\"");
    assert_non_null(u);
    u += 7;
    char *end = strchr(u, '"');
    size_t cap = len + strlen(uri) + (extra ? strlen(extra) : 0) + 16;
    char *out = malloc(cap);
    int n = snprintf(out, cap, "%.*s%s%s", (int)(u - text), text, uri, end);
    if (extra) { /* before the root's closing brace */
        out[n - 1] = 0;
        strcat(out, ",");
        strcat(out, extra);
        strcat(out, "}");
    }
    assert_int_equal(ts_write_file(path, out, strlen(out)), 0);
    free(out), free(text), free(tmp);
}

/* glTF buffers and images are read only from the .gltf's folder: no `..`
 * out of it (however encoded), no absolute path, no scheme but data:, no
 * symlink out of it. A .bin beside the .gltf (or below it) still works. */
static void test_gltf_uris(void **s)
{
    (void)s;
    char *g = ts_path(dir, "gltf_uris"), *sub = ts_path(g, "sub"), *deeper = ts_path(sub, "bin");
    mkdir(g, 0755), mkdir(sub, 0755), mkdir(deeper, 0755);
    char *outside_bin = ts_path(g, "mesh.bin"); /* a valid buffer, outside sub/ */
    char *ok = ts_path(sub, "ok.gltf"), *inner = ts_path(sub, "inner.bin");
    write_gltf_external(ok, "inner.bin", inner, NULL);
    write_gltf_external(ok, "inner.bin", outside_bin, NULL); /* the same bytes outside */
    char *ok2 = ts_path(sub, "ok2.gltf"), *inner2 = ts_path(deeper, "inner2.bin");
    write_gltf_external(ok2, "./bin/../bin/inner2.bin", inner2, NULL);
    char *ok3 = ts_path(g, "beside.gltf");
    write_gltf_external(ok3, "mesh.bin", NULL, NULL);
    const char *good[] = {ok, ok2, ok3};
    for (int i = 0; i < 3; i++) {
        mim_mesh_t m;
        mim_error_t err = {0};
        int rc = mim_io_read_mesh(good[i], &m, &err);
        if (rc) fail_msg("%s: %s", good[i], err.msg);
        assert_int_equal(m.n_vertices, sphere.n_vertices);
        mim_mesh_free(&m);
    }
    char *link = ts_path(sub, "link.bin");
    assert_int_equal(symlink("../mesh.bin", link), 0);
    char abs_uri[4200], file_uri[4200];
    snprintf(abs_uri, sizeof abs_uri, "%s", outside_bin);
    snprintf(file_uri, sizeof file_uri, "file://%s", outside_bin);
    struct {
        const char *name, *uri, *extra, *phrase;
    } bad[] = {
        {"dotdot.gltf", "../mesh.bin", NULL, "'../mesh.bin' refused: it leaves the glTF file's folder"},
        {"deep.gltf", "bin/../../mesh.bin", NULL, "'bin/../../mesh.bin' refused: it leaves the glTF file's folder"},
        {"escaped.gltf", "\\u002e\\u002e/mesh.bin", NULL, "'../mesh.bin' refused: it leaves the glTF file's folder"},
        {"percent.gltf", "%2e%2e/mesh.bin", NULL, "'../mesh.bin' refused: it leaves the glTF file's folder"},
        {"absolute.gltf", abs_uri, NULL, "refused: it is an absolute path"},
        {"file.gltf", file_uri, NULL, "refused: it is a URI with the scheme 'file:'"},
        {"http.gltf", "http://127.0.0.1:9/mesh.bin", NULL, "refused: it is a URI with the scheme 'http:'"},
        {"symlink.gltf", "link.bin", NULL, "refused: it resolves to "},
        {"passwd.gltf", "../../../../../../../../etc/passwd", NULL, "leaves the glTF file's folder"},
        {"image.gltf", "inner.bin", "\"images\":[{\"uri\":\"../mesh.bin\"}]", "'../mesh.bin' refused: it leaves"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char *p = ts_path(sub, bad[i].name);
        write_gltf_external(p, bad[i].uri, NULL, bad[i].extra);
        mim_mesh_t m;
        mim_error_t err = {0};
        int rc = mim_io_read_mesh(p, &m, &err);
        if (rc != MIM_EUNSUPPORTED || !strstr(err.msg, bad[i].phrase) || !strstr(err.msg, "refused"))
            fail_msg("%s: rc %d, message: %s", bad[i].name, rc, err.msg);
        assert_non_null(strstr(err.msg, p));
        assert_null(strchr(err.msg, '\n'));
        assert_null(m.positions);
        free(p);
    }
    /* tinygltf would also try the name from the current directory: never */
    char *cwd_gltf = ts_path(sub, "cwd.gltf"), here[4096];
    write_gltf_external(cwd_gltf, "mesh.bin", NULL, NULL); /* no sub/mesh.bin, but there is one in g */
    assert_non_null(getcwd(here, sizeof here));
    assert_int_equal(chdir(g), 0);
    mim_mesh_t m;
    mim_error_t err = {0};
    int rc = mim_io_read_mesh(cwd_gltf, &m, &err);
    assert_int_equal(chdir(here), 0);
    if (rc != MIM_EFORMAT || !strstr(err.msg, "File not found : mesh.bin")) fail_msg("cwd.gltf: rc %d, %s", rc, err.msg);
    free(cwd_gltf);
    free(link), free(ok3), free(inner2), free(ok2), free(inner), free(ok), free(outside_bin);
    free(deeper), free(sub), free(g);
}

/* A mesh that is no body (plausible.c) is reported and not stored: every
 * vertex at one point, a coordinate of 3e38. */
static void test_implausible_meshes(void **s)
{
    (void)s;
    char *data = make_dataset("ds_implausible", 3, 1);
    ts_polymesh_t m;
    ts_sphere(&m, 12, 16, 0.5f);
    for (uint32_t v = 0; v < m.n_vertices; v++) m.pos[3 * v] = 0.1f, m.pos[3 * v + 1] = 1.0f, m.pos[3 * v + 2] = 0;
    char *point = ts_path(data, "zz_point.ply");
    ts_write_ply_binary(point, &m);
    ts_polymesh_free(&m);
    ts_sphere(&m, 12, 16, 0.5f);
    m.pos[3 * 12 + 1] = 3e38f;
    char *far = ts_path(data, "zz_far.ply");
    ts_write_ply_binary(far, &m);
    ts_polymesh_free(&m);

    mim_db_t *db;
    heard_t h;
    mim_ingest_report_t rep;
    ingest_heard("store_implausible", data, &h, &db, &rep);
    assert_int_equal(rep.added, 3);
    assert_int_equal(rep.failed, 2);
    assert_int_equal(rep.templates, 3);
    assert_int_equal(h.n, 2);
    char want[4200];
    snprintf(want, sizeof want, "%s: the %u vertices span 0.0 mm: not a body (at least 10 mm)", point,
             sphere.n_vertices);
    assert_string_equal(heard_line(&h, "zz_point.ply"), want);
    snprintf(want, sizeof want, "%s: vertex 12: coordinate y = 3e+38 outside the 10 m box a body fits in", far);
    assert_non_null(strstr(heard_line(&h, "zz_far.ply"), want));
    mim_db_close(&db);
    free(far), free(point), free(data);
}

/* The real dataset, when it is beside the project: all 96 go in, labelled. */
static void test_mh_bodies(void **s)
{
    (void)s;
    char path[4096];
    snprintf(path, sizeof path, "%s/mh-bodies", ts_shared_data());
    if (access(path, R_OK) != 0) skip();
    char *store = ts_path(dir, "mh");
    char manifest[4200];
    snprintf(manifest, sizeof manifest, "%s/manifest.csv", path);
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_ingest_options_t opt = {.manifest_path = manifest};
    mim_ingest_report_t rep;
    char *paths[] = {path};
    assert_int_equal(mim_ingest_run(db, paths, 1, &opt, &rep, &err), 0);
    assert_int_equal(rep.added, 96);
    assert_int_equal(rep.failed, 0);
    assert_int_equal(rep.templates, 96);
    mim_db_close(&db);
    free(store);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_read_off),        cmocka_unit_test(test_read_ply_ascii),
        cmocka_unit_test(test_read_ply_binary), cmocka_unit_test(test_read_obj),
        cmocka_unit_test(test_read_stl_ascii),  cmocka_unit_test(test_read_stl_binary),
        cmocka_unit_test(test_read_glb),        cmocka_unit_test(test_read_gltf),
        cmocka_unit_test(test_truncated),       cmocka_unit_test(test_nonfinite),
        cmocka_unit_test(test_bad_index),       cmocka_unit_test(test_empty),
        cmocka_unit_test(test_unreadable),      cmocka_unit_test(test_malformed),
        cmocka_unit_test(test_labels),
        cmocka_unit_test(test_manifest),        cmocka_unit_test(test_discover),
        cmocka_unit_test(test_pipeline),        cmocka_unit_test(test_landmark_requirements),
        cmocka_unit_test(test_builtin_map_first_ingest),
        cmocka_unit_test(test_mh_bodies),       cmocka_unit_test(test_symlinks),
        cmocka_unit_test(test_gltf_uris),       cmocka_unit_test(test_implausible_meshes),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
