/* k-NN at scale (issue 16, item 3): FLANN's kd-forest, which the index
 * uses inside every pose class above exact_max templates, against FAISS's
 * HNSW graph on the same descriptors. Prints figures; never passes or
 * fails.
 *
 * Descriptors are mimic's own: the 60 angles an index selects on the
 * synth bodies (8 subjects x 12 poses), computed on landmarks jittered by
 * 1.5 cm per coordinate (as bench/query.c makes its templates). Two sets:
 * one pose class of 83 000 templates (what a class holds in a store of
 * 1 000 000 with 12 classes) and all 1 000 000 in one flat index. The
 * exact nearest neighbour (FAISS's flat L2 scan) is the truth for recall.
 * Queries are 2000 fresh jitters, one at a time on one thread; builds may
 * use both cores (FLANN's build is serial, FAISS's HNSW build is OpenMP).
 *
 *   bench_knn_compare [--sizes 83000,1000000] [--queries N] */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_index.h"

#include <faiss/IndexFlat.h>
#include <faiss/IndexHNSW.h>
#include <faiss/impl/io.h>
#include <faiss/index_io.h>
#include <flann/flann.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

static uint64_t rng_state = 4242;
static double uniform01()
{
    rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return ((rng_state >> 11) + 0.5) / 9007199254740992.0;
}
static double gauss() { return std::sqrt(-2 * std::log(uniform01())) * std::cos(2 * M_PI * uniform01()); }

struct Descriptors {
    uint32_t d = 0;
    std::vector<uint32_t> selected;
    std::vector<std::vector<float>> base; /* the bodies' landmarks */
    uint32_t L = 0;
};

/* n descriptors: jittered frames of the bodies (pose `only_pose`, or all
 * poses when negative). */
static std::vector<float> make(const Descriptors &D, uint32_t n, int only_pose, uint32_t poses)
{
    std::vector<float> out((size_t)n * D.d), angles(mim_index_angle_count(D.L)), frame(3 * D.L);
    uint32_t nb = (uint32_t)D.base.size();
    for (uint32_t i = 0; i < n; i++) {
        uint32_t b = only_pose >= 0 ? (i % (nb / poses)) * poses + (uint32_t)only_pose : i % nb;
        for (uint32_t k = 0; k < 3 * D.L; k++) frame[k] = D.base[b][k] + (float)(0.015 * gauss());
        mim_index_angles(frame.data(), nullptr, D.L, angles.data());
        for (uint32_t f = 0; f < D.d; f++) out[(size_t)i * D.d + f] = angles[D.selected[f]];
    }
    return out;
}

struct Row {
    std::string method;
    double build_s, median_us, p99_us, recall, ratio, mib;
};

static void print_rows(const char *title, const std::vector<Row> &rows)
{
    std::printf("\n### %s\n\n| method | build (s) | memory (MiB) | median (us) | p99 (us) | recall@1 | distance / exact |\n"
                "|---|---:|---:|---:|---:|---:|---:|\n",
                title);
    for (const Row &r : rows)
        std::printf("| %s | %.2f | %.1f | %.1f | %.1f | %.3f | %.4f |\n", r.method.c_str(), r.build_s, r.mib, r.median_us,
                    r.p99_us, r.recall, r.ratio);
}

template <typename Search>
static Row timed(const std::string &name, double build_s, double mib, const std::vector<float> &q, uint32_t nq, uint32_t d,
                 const std::vector<faiss::Index::idx_t> &truth, const std::vector<float> &truth_d, Search search)
{
    std::vector<double> t(nq);
    uint32_t agree = 0;
    double ratio = 0;
    for (uint32_t i = 0; i < nq; i++) {
        float dist;
        long id;
        double s = mim_now();
        search(q.data() + (size_t)i * d, &id, &dist);
        t[i] = (mim_now() - s) * 1e6;
        agree += id == truth[i];
        ratio += truth_d[i] > 0 ? std::sqrt(dist / truth_d[i]) : 1.0;
    }
    Row r{name, build_s, 0, 0, (double)agree / nq, ratio / nq, mib};
    r.median_us = bench_median(t.data(), (int)nq);
    r.p99_us = bench_quantile(t.data(), (int)nq, 0.99);
    return r;
}

int main(int argc, char **argv)
{
    std::vector<uint32_t> sizes = {83000, 1000000};
    uint32_t nq = 2000;
    for (int i = 1; i < argc; i++) {
        if (!std::strcmp(argv[i], "--sizes") && i + 1 < argc) {
            sizes.clear();
            for (char *p = std::strtok(argv[++i], ","); p; p = std::strtok(nullptr, ",")) sizes.push_back((uint32_t)std::atol(p));
        } else if (!std::strcmp(argv[i], "--queries") && i + 1 < argc) {
            nq = (uint32_t)std::atol(argv[++i]);
        } else {
            std::fprintf(stderr, "usage: bench_knn_compare [--sizes 83000,1000000] [--queries N]\n");
            return 2;
        }
    }
    bench_dataset_t ds;
    const uint32_t subjects = 8, poses = 12;
    if (bench_load_synth(&ds, subjects, poses, 3000)) return 1;
    Descriptors D;
    D.L = ds.map.count;
    std::vector<float> lm;
    std::vector<uint64_t> ids;
    std::vector<std::string> subj, pose;
    for (uint32_t t = 0; t < subjects * poses; t++) {
        std::vector<float> f(3 * D.L);
        for (uint32_t l = 0; l < D.L; l++)
            for (int c = 0; c < 3; c++) f[3 * l + c] = ds.pos[t][3 * (size_t)ds.map.vertex[l] + c];
        D.base.push_back(f);
        lm.insert(lm.end(), f.begin(), f.end());
        ids.push_back(t + 1), subj.push_back("s" + std::to_string(t / poses)), pose.push_back("p" + std::to_string(t % poses));
    }
    std::vector<const char *> sp, pp;
    for (uint32_t t = 0; t < subjects * poses; t++) sp.push_back(subj[t].c_str()), pp.push_back(pose[t].c_str());
    int32_t parent[MIM_LANDMARKS_MAX]; // as mimic index: canonical proportions
    mim_index_input_t in = {subjects * poses, D.L, lm.data(), ids.data(), sp.data(), pp.data(), ds.map.mirror,
                            mim_index_skeleton(&ds.map, parent) ? nullptr : parent};
    mim_index_t *ix = nullptr;
    mim_error_t err = {};
    if (mim_index_build(&ix, &in, nullptr, nullptr, &err)) {
        std::fprintf(stderr, "bench: %s\n", mim_error_text(&err));
        return 1;
    }
    mim_index_info_t info;
    mim_index_get_info(ix, &info);
    D.d = info.d;
    D.selected.assign(mim_index_selected(ix), mim_index_selected(ix) + D.d);
    mim_index_close(&ix);
    std::printf("descriptors: the %u angles an index selects on synth (8 x 12), landmarks jittered 1.5 cm; "
                "%u queries, one at a time, one thread\n",
                D.d, nq);
    for (uint32_t n : sizes) {
        bool one_class = n < 200000;
        std::vector<float> x = make(D, n, one_class ? 0 : -1, poses), q = make(D, nq, one_class ? 0 : -1, poses);
        /* the truth: an exact scan */
        faiss::IndexFlatL2 flat(D.d);
        flat.add(n, x.data());
        std::vector<faiss::Index::idx_t> truth(nq);
        std::vector<float> truth_d(nq);
        omp_set_num_threads(2);
        flat.search(nq, q.data(), 1, truth_d.data(), truth.data());
        std::vector<Row> rows;
        omp_set_num_threads(1);
        rows.push_back(timed("exact scan (FAISS flat L2)", 0, (double)n * D.d * 4 / 1048576, q, nq, D.d, truth, truth_d,
                             [&](const float *v, long *id, float *dist) {
                                 faiss::Index::idx_t i;
                                 flat.search(1, v, 1, dist, &i);
                                 *id = (long)i;
                             }));
        /* FLANN's kd-forest as the index builds it: 4 trees */
        FLANNParameters p = DEFAULT_FLANN_PARAMETERS;
        p.algorithm = FLANN_INDEX_KDTREE, p.trees = 4, p.cores = 1, p.log_level = FLANN_LOG_NONE, p.random_seed = 0;
        float speedup = 0;
        double t0 = mim_now();
        flann_index_t fi = flann_build_index_float(x.data(), (int)n, (int)D.d, &speedup, &p);
        double flann_build = mim_now() - t0;
        double flann_mib = flann_used_memory_float(fi) / 1048576.0;
        for (int checks : {32, 128, 512}) {
            p.checks = checks;
            rows.push_back(timed("FLANN kd-forest, 4 trees, " + std::to_string(checks) + " checks" +
                                     (checks == 128 ? " (mimic's)" : ""),
                                 flann_build, flann_mib, q, nq, D.d, truth, truth_d, [&](const float *v, long *id, float *dist) {
                                     int i;
                                     flann_find_nearest_neighbors_index_float(fi, const_cast<float *>(v), 1, &i, dist, 1, &p);
                                     *id = i;
                                 }));
        }
        flann_free_index_float(fi, &p);
        /* FAISS HNSW, M = 32 (its usual setting), efConstruction 40 */
        omp_set_num_threads(2);
        faiss::IndexHNSWFlat hnsw(D.d, 32);
        t0 = mim_now();
        hnsw.add(n, x.data());
        double hnsw_build = mim_now() - t0;
        faiss::VectorIOWriter w;
        faiss::write_index(&hnsw, &w);
        double hnsw_mib = w.data.size() / 1048576.0;
        omp_set_num_threads(1);
        for (int ef : {16, 64, 256}) {
            hnsw.hnsw.efSearch = ef;
            rows.push_back(timed("FAISS HNSW32, efSearch " + std::to_string(ef) + " (build on 2 cores)", hnsw_build, hnsw_mib, q,
                                 nq, D.d, truth, truth_d, [&](const float *v, long *id, float *dist) {
                                     faiss::Index::idx_t i;
                                     hnsw.search(1, v, 1, dist, &i);
                                     *id = (long)i;
                                 }));
        }
        char title[160];
        std::snprintf(title, sizeof title, "%u descriptors (%s)", n, one_class ? "one pose class" : "all poses, one flat index");
        print_rows(title, rows);
        std::fflush(stdout);
    }
    bench_dataset_free(&ds);
    return 0;
}
