/* Argument helpers shared by the subcommands. */
#ifndef MIM_CLI_ARGS_H
#define MIM_CLI_ARGS_H

#include "mim_db.h"

#include <stdint.h>

/* Parses a whole decimal number in [lo, hi] (no sign, no trailing text) given
 * to option --name of command cmd. On failure prints one line,
 * "mimic CMD: --NAME 'TEXT' is not a number in LO..HI", and returns -1. */
int mim_cli_number(const char *cmd, const char *name, const char *text, uint64_t lo, uint64_t hi, uint64_t *out);

/* Parses a finite real number in [lo, hi] ((lo, hi] when lo_open) given to
 * option --name of command cmd. On failure prints one line, "mimic CMD:
 * --NAME 'TEXT' WHAT" (what: e.g. "is not a positive number of metres";
 * NULL: "is not a number in LO..HI"), and returns -1. */
int mim_cli_real(const char *cmd, const char *name, const char *text, double lo, double hi, int lo_open,
                 const char *what, double *out);

/* --key-rate: "auto" (0) or key frames per second in (0, 1000]. Prints one
 * line and returns -1 otherwise. */
int mim_cli_key_rate(const char *cmd, const char *text, double *out);

/* --listen HOST:PORT (PORT all digits): the length of HOST, or -1 after
 * printing one line. */
int mim_cli_listen(const char *cmd, const char *listen);

/* A template id (a whole number >= 1, as mimic list shows) given to
 * --name. Prints one line and returns -1 otherwise. */
int mim_cli_template_id(const char *cmd, const char *name, const char *text, uint64_t *id);
/* "on" -> 1, "off" -> 0; -1 after a line on stderr. */
int mim_cli_on_off(const char *cmd, const char *name, const char *text, int *out);
/* A comma-separated list of 1..max template ids into ids (*n of them); -1
 * after a line on stderr. */
int mim_cli_template_ids(const char *cmd, const char *name, const char *text, uint64_t *ids, uint32_t max,
                         uint32_t *n);

/* Store options for every command: read_only, the LMDB map size from
 * MIMIC_MAP_SIZE (bytes; unset or not a whole number: the default), and the
 * terminal's progress line and log for a migration of an older store. */
mim_db_options_t mim_cli_db_options(int read_only);

/* The wearer's pose at the tare given to --name: rest, t or a (T and A
 * too), as MIM_VEST_POSE_*. Prints one line and returns -1 otherwise. */
int mim_cli_pose(const char *cmd, const char *name, const char *text, int *pose);
/* --drive auto|template|orientation (mim_session_drive_t); -1 with a line on stderr. */
int mim_cli_drive(const char *cmd, const char *text, int *drive);

/* Session options for every command that opens one: the map size
 * (mim_cli_db_options), the log on the terminal, and --avatar-landmarks
 * (NULL when not given) for an avatar of another connectivity. */
struct mim_session_options;
/* The options of a command that loads an avatar (transfer, morph, serve):
 * --avatar-landmarks FILE, --avatar-mesh NAME (repeatable), --max-distance-mm MM. */
#define MIM_CLI_AVATAR_MESHES_MAX 64
typedef struct mim_cli_avatar {
    const char *landmarks;
    const char *meshes[MIM_CLI_AVATAR_MESHES_MAX];
    uint32_t n_meshes;
    double max_distance_mm;
} mim_cli_avatar_t;
#define MIM_CLI_OPT_AVATAR_MESH 1001
#define MIM_CLI_OPT_MAX_DISTANCE 1002
#define MIM_CLI_AVATAR_LONGOPTS                                                                                        \
    {"avatar-mesh", required_argument, 0, MIM_CLI_OPT_AVATAR_MESH},                                                    \
    {"max-distance-mm", required_argument, 0, MIM_CLI_OPT_MAX_DISTANCE}
#define MIM_CLI_AVATAR_HELP                                                                                            \
    "  --avatar-mesh NAME   a glTF avatar: drive only the meshes (or nodes) of that name (repeatable;\n"             \
    "                       default: every primitive of the scene)\n"                                                 \
    "  --max-distance-mm MM refuse an avatar whose registration's surface distance p95 is over MM\n"                  \
    "                       (default 15; a stylised avatar may need more)\n"
/* Takes option c (getopt's value) when it is one of the two above: 1 when
 * taken, -1 after a one-line error on stderr (exit 2), 0 when c is another. */
int mim_cli_avatar_option(const char *cmd, int c, const char *arg, mim_cli_avatar_t *a);
/* avatar may be NULL (a command without one). */
void mim_cli_session_options(struct mim_session_options *so, const mim_cli_avatar_t *avatar);

/* For --register and mimic register: the store's index (a query) and a
 * registrar over the store's connectivity that finds starting templates
 * through it (mim_ingest_registrar_open with mim_query_nearest). Prints
 * one line and returns 2 when the store is empty or has no index. */
struct mim_query;
struct mim_ingest_registrar;
int mim_cli_registrar_open(mim_db_t *db, const char *cmd, struct mim_query **q, struct mim_ingest_registrar **r);

#endif
