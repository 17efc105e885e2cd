/* mimic pairs retrieve: a 3D pose-pair for each 2D annotation (seed 002's
 * Fig. 2), the sample whose projection matches it best over views
 * (sample/retrieve.c). With the annotated takes (--truth) each retrieved
 * pair's 3D error is measured; with the true cameras (--cameras, as pairs
 * annotate writes them) the error of its view too. JSON report:
 * schemas/pairs-retrieve.schema.json; the lifted pairs: schemas/pair-samples.md. */
#include "args.h"
#include "commands.h"
#include "mim_sample.h"
#include "output.h"
#include "pairs_input.h"

#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define CMD "pairs retrieve"
#define N MIM_PAIR_JOINTS

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic pairs retrieve --annotations ANN.json --samples SAMPLES.jsonl -o LIFTED.jsonl\n"
            "                            [--truth A.bvh,B.bvh ...] [--cameras CAMS.json] [--threads N]\n"
            "                            [--joint-map FILE.json] [--unit M] [--up AXIS] [--json]\n\n"
            "A 3D pose-pair for each 2D annotation (seed 002's Fig. 2): the sample whose orthographic\n"
            "projection matches the annotation best over views (eq. 9's 2D distance: both centred and\n"
            "scaled to unit RMS radius, turned in the image plane by least squares). LIFTED holds, per\n"
            "annotation in order, that sample (its joints and log density) and a \"retrieved\" object:\n"
            "the annotation's take, frame and view, the sample's index and line, the view found (the\n"
            "direction the camera looks, the sample's axes) and the 2D residual\n"
            "(schemas/pair-samples.md).\n\n"
            "  --annotations F  2D annotations (mimic pairs annotate, schemas/pair-annotations.schema.json)\n"
            "  --samples F      the pose-pairs to retrieve from (mimic pairs sample or pairs export)\n"
            "  --truth A,B      the annotated takes, in the order pairs annotate had them (--pair): each\n"
            "                   retrieved pair's 3D error against its annotation's true frame, the mean\n"
            "                   distance of the 34 joints after a rigid fit, metres\n"
            "  --cameras F      the true cameras (pairs annotate --cameras), with --truth: the angle\n"
            "                   between the view found and the true camera's, after the same fit\n"
            "  --threads N      threads (default: one per core)\n"
            "  --json           a report on stdout (schemas/pairs-retrieve.schema.json)\n"
            "  -o FILE          the lifted pose-pairs, JSON lines, written atomically\n"
            "  --joint-map, --unit, --up: how --truth is read (mimic pairs --help)\n\n"
            "Exit status: 0 done, 1 an input failed (annotations, samples, takes, cameras), 2 bad usage.\n");
}

/* Mean, median and 95th percentile of v[n] (sorted in place) as a JSON object; null for none. */
static json_t *summary(double *v, uint32_t n)
{
    if (!n) return json_null();
    for (uint32_t i = 1; i < n; i++) /* insertion sort: annotations number thousands at most */
        for (uint32_t k = i; k > 0 && v[k] < v[k - 1]; k--) {
            double t = v[k];
            v[k] = v[k - 1], v[k - 1] = t;
        }
    double mean = 0;
    for (uint32_t i = 0; i < n; i++) mean += v[i] / n;
    return json_pack("{s:f, s:f, s:f}", "mean", mean, "median", v[n / 2], "p95", v[(uint32_t)(0.95 * (n - 1))]);
}

/* The true cameras, one per annotation in its order (take, frame and view
 * checked): each camera's forward axis (its rotation's third row) into
 * fwd[3 * n]. 0, or -1 after printing. */
static int read_cameras(const char *path, const mim_pairs_annotations_t *ann, double *fwd)
{
    json_error_t je;
    json_t *j = json_load_file(path, 0, &je);
    if (!j) {
        fprintf(stderr, "mimic " CMD ": %s:%d:%d: %s\n", path, je.line, je.column, je.text);
        return -1;
    }
    json_t *cams = json_object_get(j, "cameras");
    const char *fmt = json_string_value(json_object_get(j, "format"));
    int rc = -1;
    if (!fmt || strcmp(fmt, "mimic pair cameras 1") || !json_is_array(cams)) {
        fprintf(stderr, "mimic " CMD ": %s: not a cameras file (format \"mimic pair cameras 1\", \"cameras\": [...])\n",
                path);
    } else if (json_array_size(cams) != ann->n) {
        fprintf(stderr, "mimic " CMD ": %s: %zu cameras for %u annotations: give the cameras of these annotations\n",
                path, json_array_size(cams), ann->n);
    } else {
        rc = 0;
        for (uint32_t i = 0; i < ann->n && !rc; i++) {
            json_t *c = json_array_get(cams, i), *R = json_object_get(c, "rotation");
            json_int_t t = json_integer_value(json_object_get(c, "take")), f = json_integer_value(json_object_get(c, "frame")),
                       v = json_integer_value(json_object_get(c, "view"));
            if (t != ann->take[i] || f != ann->frame[i] || v != ann->view[i]) {
                fprintf(stderr, "mimic " CMD ": %s: camera %u is take %lld frame %lld view %lld, annotation %u take %u "
                                "frame %u view %u\n", path, i + 1, (long long)t, (long long)f, (long long)v, i + 1,
                        ann->take[i], ann->frame[i], ann->view[i]);
                rc = -1;
                break;
            }
            double n2 = 0;
            for (int k = 0; k < 3; k++) {
                json_t *x = json_array_get(R, 6 + (size_t)k);
                fwd[3 * i + k] = json_number_value(x);
                n2 += fwd[3 * i + k] * fwd[3 * i + k];
                if (!json_is_number(x)) n2 = NAN;
            }
            if (json_array_size(R) != 9 || !(fabs(n2 - 1) < 1e-3)) {
                fprintf(stderr, "mimic " CMD ": %s: camera %u: \"rotation\" is not 9 numbers of a rotation\n", path, i + 1);
                rc = -1;
            }
        }
    }
    json_decref(j);
    return rc;
}

/* The lifted pose-pairs, one line per annotation, written atomically. */
static int write_lifted(const char *path, const mim_pairs_annotations_t *ann, const mim_pairs_samples_t *smp,
                        const mim_pairs_match_t *m, const double *err3d, const double *view_err)
{
    char *head = mim_pairs_jsonl_header();
    size_t cap = 1 << 16, len = 0;
    char *text = malloc(cap);
    int rc = head && text ? 0 : -1;
    for (int64_t i = -1; i < (int64_t)ann->n && !rc; i++) {
        char *line = NULL;
        if (i < 0) {
            line = strdup(head);
        } else if (m[i].sample == UINT32_MAX) {
            continue;
        } else {
            const uint32_t s = m[i].sample;
            char *base = mim_pairs_jsonl_line(smp->joints + (size_t)s * 3 * N, smp->log_density[s]);
            json_t *o = base ? json_loads(base, 0, NULL) : NULL;
            json_t *r = json_pack("{s:I, s:I, s:I, s:I, s:I, s:I, s:[f, f, f], s:f}", "annotation", (json_int_t)i + 1,
                                  "take", (json_int_t)ann->take[i], "frame", (json_int_t)ann->frame[i], "view",
                                  (json_int_t)ann->view[i], "sample", (json_int_t)s + 1, "sample_line",
                                  (json_int_t)(smp->line ? smp->line[s] : 0), "direction", m[i].dir[0], m[i].dir[1],
                                  m[i].dir[2], "residual", m[i].residual);
            if (r && err3d && isfinite(err3d[i])) json_object_set_new(r, "error_m", json_real(err3d[i]));
            if (r && view_err && isfinite(view_err[i])) json_object_set_new(r, "view_error_deg", json_real(view_err[i]));
            if (o && r) json_object_set_new(o, "retrieved", r), r = NULL;
            line = o ? json_dumps(o, JSON_COMPACT | JSON_PRESERVE_ORDER) : NULL;
            json_decref(o), json_decref(r);
            free(base);
        }
        if (!line) {
            rc = -1;
            break;
        }
        size_t l = strlen(line);
        while (len + l + 2 > cap) {
            char *g = realloc(text, cap *= 2);
            if (!g) {
                rc = -1;
                break;
            }
            text = g;
        }
        if (!rc) memcpy(text + len, line, l), len += l, text[len++] = '\n';
        free(line);
    }
    if (rc) fprintf(stderr, "mimic " CMD ": out of memory for the lifted pose-pairs\n");
    else rc = mim_cli_pairs_write(CMD, path, text, len);
    free(head), free(text);
    return rc;
}

int mim_cmd_pairs_retrieve(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"annotations", required_argument, 0, 'a'}, {"samples", required_argument, 0, 's'},
        {"output", required_argument, 0, 'o'},      {"truth", required_argument, 0, 'p'},
        {"cameras", required_argument, 0, 'c'},     {"threads", required_argument, 0, 't'},
        {"joint-map", required_argument, 0, 'm'},   {"unit", required_argument, 0, 'u'},
        {"up", required_argument, 0, MIM_CLI_OPT_UP}, {"json", no_argument, 0, 'j'},
        {"help", no_argument, 0, 'h'},              {0, 0, 0, 0},
    };
    const char *ann_path = NULL, *samples_path = NULL, *out_path = NULL, *cams_path = NULL;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    uint64_t threads = cores > 0 ? (uint64_t)cores : 1;
    mim_cli_takes_t tk = {.cmd = CMD, .every = 1};
    int as_json = 0, c, taken;
    optind = 0, opterr = 0;
    while ((c = getopt_long(argc, argv, "a:s:o:p:c:t:m:u:jh", longopts, NULL)) != -1) {
        if ((taken = mim_cli_takes_option(&tk, c, optarg))) {
            if (taken < 0) return 2;
            continue;
        }
        switch (c) {
        case 'a': ann_path = optarg; break;
        case 's': samples_path = optarg; break;
        case 'o': out_path = optarg; break;
        case 'c': cams_path = optarg; break;
        case 'j': as_json = 1; break;
        case 't':
            if (mim_cli_number(CMD, "threads", optarg, 1, 256, &threads)) return 2;
            break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic " CMD ": unknown or incomplete option '%s' (see mimic " CMD " --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!ann_path || !samples_path || !out_path) {
        fprintf(stderr, "mimic " CMD ": --annotations, --samples and -o are required (see mimic " CMD " --help)\n");
        return 2;
    }
    if (cams_path && !tk.n) {
        fprintf(stderr, "mimic " CMD ": --cameras needs the annotated takes (--truth A,B ...)\n");
        return 2;
    }
    if (optind < argc) {
        fprintf(stderr, "mimic " CMD ": unexpected argument '%s'\n", argv[optind]);
        return 2;
    }
    if (mim_cli_takes_begin(&tk)) return 1;
    mim_error_t err = {0};
    mim_pairs_annotations_t ann = {0};
    mim_pairs_samples_t smp = {0};
    char *text = NULL;
    size_t len;
    double **truth = calloc((size_t)(tk.n ? tk.n : 1), sizeof *truth);
    uint32_t *n_truth = calloc((size_t)(tk.n ? tk.n : 1), sizeof *n_truth);
    mim_pairs_match_t *m = NULL;
    double *err3d = NULL, *view_err = NULL, *fwd = NULL, *res = NULL;
    int status = 1;
    if (!truth || !n_truth) {
        fprintf(stderr, "mimic " CMD ": out of memory\n");
        goto done;
    }
    if (mim_file_read(ann_path, 0, &text, &len, &err) || mim_pairs_annotations_parse(text, len, ann_path, &ann, &err)) {
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
        goto done;
    }
    free(text), text = NULL;
    if (mim_cli_samples_read(CMD, samples_path, &smp)) goto done;
    for (int t = 0; t < tk.n; t++)
        if (mim_cli_takes_read(&tk, t, &truth[t], &n_truth[t])) goto done;
    for (uint32_t i = 0; i < ann.n && tk.n; i++)
        if (ann.take[i] >= (uint32_t)tk.n || ann.frame[i] >= n_truth[ann.take[i]]) {
            fprintf(stderr, "mimic " CMD ": %s: annotation %u is of take %u frame %u, which the %d --truth take%s do "
                            "not have: give the takes pairs annotate had, in its order\n",
                    ann_path, i + 1, ann.take[i], ann.frame[i], tk.n, tk.n == 1 ? "" : "s");
            goto done;
        }
    m = malloc((size_t)ann.n * sizeof *m);
    res = malloc((size_t)ann.n * sizeof *res);
    err3d = tk.n ? malloc((size_t)ann.n * sizeof *err3d) : NULL;
    view_err = cams_path ? malloc((size_t)ann.n * sizeof *view_err) : NULL;
    fwd = cams_path ? malloc((size_t)ann.n * 3 * sizeof *fwd) : NULL;
    if (!m || !res || (tk.n && !err3d) || (cams_path && (!view_err || !fwd))) {
        fprintf(stderr, "mimic " CMD ": out of memory for %u annotations\n", ann.n);
        goto done;
    }
    if (cams_path && read_cameras(cams_path, &ann, fwd)) goto done;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    mim_progress_t pr = {.fn = mim_cli_progress};
    mim_pairs_retrieve_many(smp.joints, smp.n, &ann, (uint32_t)threads, &pr, m);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    uint32_t found = 0, n3 = 0, nv = 0;
    for (uint32_t i = 0; i < ann.n; i++) {
        if (m[i].sample == UINT32_MAX) continue;
        res[found++] = m[i].residual;
        if (!tk.n) continue;
        /* one rigid fit of the sample onto the true frame: the joints' mean distance, and the view turned by it */
        const double *g = truth[ann.take[i]] + (size_t)ann.frame[i] * 3 * N;
        const double *s = smp.joints + (size_t)m[i].sample * 3 * N;
        double R[9], t[3], d = 0;
        mim_sample_rigid_fit(g, s, NULL, R, t);
        for (int k = 0; k < N; k++) {
            double e2 = 0;
            for (int r = 0; r < 3; r++) {
                const double x = R[3 * r] * s[3 * k] + R[3 * r + 1] * s[3 * k + 1] + R[3 * r + 2] * s[3 * k + 2] + t[r];
                e2 += (g[3 * k + r] - x) * (g[3 * k + r] - x);
            }
            d += sqrt(e2) / N;
        }
        err3d[i] = d;
        if (cams_path) { /* the view found against the camera's forward axis */
            double dot = 0;
            for (int r = 0; r < 3; r++)
                dot += (R[3 * r] * m[i].dir[0] + R[3 * r + 1] * m[i].dir[1] + R[3 * r + 2] * m[i].dir[2]) * fwd[3 * i + r];
            view_err[i] = acos(fmax(-1.0, fmin(1.0, dot))) * 180 / M_PI;
        }
    }
    if (write_lifted(out_path, &ann, &smp, m, err3d, view_err)) goto done;
    /* the figures (the arrays sorted for them, after the file) */
    for (uint32_t i = 0; i < ann.n && tk.n; i++)
        if (m[i].sample != UINT32_MAX) {
            err3d[n3++] = err3d[i];
            if (cams_path && isfinite(view_err[i])) view_err[nv++] = view_err[i];
        }
    json_t *jr = summary(res, found), *je = summary(err3d, n3), *jv = summary(view_err, nv);
    double seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    if (as_json) {
        json_t *j = json_pack("{s:I, s:I, s:I, s:o, s:o, s:o, s:f}", "annotations", (json_int_t)ann.n, "retrieved",
                              (json_int_t)found, "samples", (json_int_t)smp.n, "residual", jr, "error_m", je,
                              "view_error_deg", jv, "seconds", seconds);
        char *out = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (out) printf("%s\n", out);
        else fprintf(stderr, "mimic " CMD ": cannot make the JSON report\n");
        free(out);
        json_decref(j);
    } else {
        printf("%u of %u annotations lifted from %u samples in %.1f s", found, ann.n, smp.n, seconds);
        if (found) printf("; 2D residual median %.4f", json_real_value(json_object_get(jr, "median")));
        if (n3) printf("; 3D error median %.3f m (mean %.3f)", json_real_value(json_object_get(je, "median")),
                       json_real_value(json_object_get(je, "mean")));
        if (nv) printf("; view error median %.1f deg", json_real_value(json_object_get(jv, "median")));
        printf("\n");
        json_decref(jr), json_decref(je), json_decref(jv);
    }
    status = found == ann.n ? 0 : 1;
    if (status) fprintf(stderr, "mimic " CMD ": %u annotations matched no sample (points all at one place)\n", ann.n - found);
done:
    for (int t = 0; t < tk.n && truth; t++) free(truth[t]);
    free(truth), free(n_truth), free(m), free(res), free(err3d), free(view_err), free(fwd), free(text), free(tk.map_text);
    mim_pairs_annotations_free(&ann);
    mim_pairs_samples_free(&smp);
    return status;
}
