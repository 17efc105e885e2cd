/* Landmark maps of known connectivities, built in (the JSON files in register/maps/):
 * a mesh whose faces hash to a map's "faces_sha256" gets that map without
 * the user bringing one (FAUST and every SMPL-family mesh share SMPL's
 * 6890-vertex connectivity). The hash is SHA-256 (OpenSSL EVP) of the
 * triangle indices as little-endian uint32, three per triangle, in order,
 * whatever the host's byte order, so that the digests in the map files
 * (computed once, elsewhere) hold on every machine. Nothing is cached:
 * each call parses the small built-in texts again, so there is no global
 * state to guard between threads. */
#include "mim_register.h"
#include "known_maps.h"

#include <jansson.h>
#include <openssl/evp.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

void mim_reg_faces_sha256(const uint32_t *faces, uint32_t n_faces, char hex[65])
{
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int md_len = 0;
    unsigned char buf[4096]; /* the indices as little-endian bytes, a chunk at a time */
    size_t n = (size_t)n_faces * 3, done = 0;
    hex[0] = '\0'; /* what a failure leaves: it matches no map */
    EVP_MD_CTX *ctx = EVP_MD_CTX_new();
    if (!ctx)
        return;
    int ok = EVP_DigestInit_ex(ctx, EVP_sha256(), NULL);
    while (ok && done < n) {
        size_t k = n - done < sizeof buf / 4 ? n - done : sizeof buf / 4;
        for (size_t i = 0; i < k; i++) {
            uint32_t v = faces[done + i];
            buf[4 * i] = (unsigned char)v;
            buf[4 * i + 1] = (unsigned char)(v >> 8);
            buf[4 * i + 2] = (unsigned char)(v >> 16);
            buf[4 * i + 3] = (unsigned char)(v >> 24);
        }
        ok = EVP_DigestUpdate(ctx, buf, 4 * k);
        done += k;
    }
    ok = ok && EVP_DigestFinal_ex(ctx, md, &md_len) && md_len == 32;
    EVP_MD_CTX_free(ctx);
    if (!ok)
        return;
    for (unsigned i = 0; i < 32; i++)
        snprintf(hex + 2 * i, 3, "%02x", md[i]);
}

int mim__known_map_match(const char *json_text, const char *name, const char *hex, uint32_t n_vertices,
                         mim_landmark_map_t *map, mim_error_t *err)
{
    char origin[160];
    snprintf(origin, sizeof origin, "built-in map %s", name ? name : "(unnamed)");
    json_error_t je;
    json_t *root = json_loads(json_text, JSON_REJECT_DUPLICATES, &je);
    if (!root)
        return mim_error_set(err, MIM_EFORMAT, "%s:%d:%d: %s", origin, je.line, je.column, je.text);
    json_t *tv = json_object_get(root, "topology_vertices");
    json_t *sha = json_object_get(root, "faces_sha256");
    int rc;
    if (!json_is_integer(tv) || !json_is_string(sha) || json_string_length(sha) != 64)
        rc = mim_error_set(err, MIM_EFORMAT,
                           "%s: needs \"topology_vertices\" and a 64-digit hex \"faces_sha256\"", origin);
    else if (json_integer_value(tv) != (json_int_t)n_vertices || !hex || strlen(hex) != 64 ||
             strcasecmp(json_string_value(sha), hex) != 0)
        rc = 0;
    else if ((rc = mim_landmarks_parse(map, json_text, strlen(json_text), origin, err)) == 0 &&
             (rc = mim_landmarks_validate(map, n_vertices, origin, err)) == 0)
        rc = 1;
    json_decref(root);
    return rc;
}

int mim_reg_known_map(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices, mim_landmark_map_t *map,
                      const char **name)
{
    if (!map || (!faces && n_faces))
        return 0;
    /* Hashed up front, even when no map has n_vertices: a million faces
     * take milliseconds beside the registration that follows. */
    char hex[65];
    mim_reg_faces_sha256(faces, n_faces, hex);
    for (unsigned i = 0; i < mim__known_map_count; i++) {
        mim_landmark_map_t m;
        /* A built-in map that does not parse is a build defect (the tests
         * parse every one); here it only means "not this map". */
        if (mim__known_map_match(mim__known_map_texts[i], mim__known_map_names[i], hex, n_vertices, &m, NULL) != 1)
            continue;
        *map = m;
        if (name)
            *name = mim__known_map_names[i];
        return 1;
    }
    return 0;
}

uint32_t mim_reg_known_map_count(void) { return mim__known_map_count; }
const char *mim_reg_known_map_name(uint32_t i) { return i < mim__known_map_count ? mim__known_map_names[i] : NULL; }
const char *mim_reg_known_map_text(uint32_t i) { return i < mim__known_map_count ? mim__known_map_texts[i] : NULL; }
