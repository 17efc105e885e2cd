/* The fixture of the sampled-templates tests (test_pairs_templates through
 * the binary, test_session_pairs through session/'s API): a synth store,
 * subject 0 at rest as pose-pair joints, and people posed from it whose
 * poses the store does not have. */
#ifndef MIM_TEST_PAIRS_SUPPORT_H
#define MIM_TEST_PAIRS_SUPPORT_H

#include "test_support.h"

#include "mim_db.h"
#include "mim_sample.h"

#define TP_J MIM_PAIR_PERSON_JOINTS
#define TP_SUBJECTS 3
#define TP_POSES 4
#define TP_OLD (TP_SUBJECTS * TP_POSES) /* the store's templates */

/* The index of a pose-pair joint by name (fails the test when none). */
int tp_joint(const char *name);
/* Turns the named joints about joint `about` by angle a around axis x, y
 * or z (radians). */
void tp_turn(double p[TP_J][3], const char *about, char axis, double a, const char *const *names);
/* The whole person turned about the vertical through the origin, then moved. */
void tp_place(double p[TP_J][3], double a, double dx, double dz);
/* A person's landmarks in map's order (3 * count floats). */
void tp_landmarks_of(const mim_landmark_map_t *map, double p[TP_J][3], float *out);

/* synth (TP_SUBJECTS x TP_POSES, 1500 vertices) into DIR/bodies, ingested
 * into DIR/store and indexed (both malloc'd into *bodies and *store); map
 * gets the landmark map, rest subject 0 at rest (template 1) as pose-pair
 * joints, the neck between head and chest. 0, or non-zero. */
int tp_synth_store(const char *dir, char **bodies, char **store, mim_landmark_map_t *map, double rest[TP_J][3]);
/* A copy of store's data.mdb in DIR/NAME (malloc'd). */
char *tp_copy_store(const char *dir, const char *store, const char *name);
/* store opened read-only with a read transaction (mim_db_abort, then
 * mim_db_close, when done). */
void tp_begin_read(const char *store, mim_db_t **db, mim_db_txn_t **t);
/* Template id (into v), which must be there with its encoding. */
void tp_template_encoded(mim_db_txn_t *t, uint64_t id, mim_template_view_t *v);

/* Four people from rest, each with limbs turned into a pose the store
 * does not have (its poses: rest, T, arms up, walk), facing +Z with the
 * body's left +X unless moved: 0 the left arm straight forward; 1 the
 * right leg lifted forward, turned to face person 0, 1.5 m away; 2 the
 * right arm forward and up, the left forearm bent forward; 3 the left knee
 * bent back and the left arm out and up, turned a quarter, elsewhere. */
#define TP_PEOPLE 4
void tp_make_people(double rest[TP_J][3], double people[TP_PEOPLE][TP_J][3]);

#endif
