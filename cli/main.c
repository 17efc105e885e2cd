/* mimic: one binary, one subcommand per user task. */
#include "commands.h"
#include "mim_core.h"

#include <stdio.h>
#include <string.h>

static const struct {
    const char *name;
    int (*fn)(int, char **);
    const char *what;
} commands[] = {
    {"synth", mim_cmd_synth, "generate synthetic human bodies (subjects x poses, one connectivity)"},
    {"ingest", mim_cmd_ingest, "put mesh files into a template store"},
    {"info", mim_cmd_info, "describe a template store"},
    {"store", mim_cmd_store, "check a template store's integrity, or migrate an older one"},
    {"list", mim_cmd_list, "list the templates of a store"},
    {"index", mim_cmd_index, "build the pose recognition index of a store"},
    {"register", mim_cmd_register, "register a mesh of another connectivity onto the store's"},
    {"landmarks", mim_cmd_landmarks, "the landmarks mimic would use for a mesh, and the built-in maps"},
    {"query", mim_cmd_query, "find the nearest-pose templates of landmark frames"},
    {"transfer", mim_cmd_transfer, "deform an avatar into a template's pose and/or landmarks"},
    {"morph", mim_cmd_morph, "key poses and the poses between them, as a GLB animation"},
    {"vest", mim_cmd_vest, "list, record, replay or simulate a tracking vest"},
    {"serve", mim_cmd_serve, "serve pose transfer: viewer, WebSocket avatar stream, JSON API"},
    {"complete", mim_cmd_complete, "fill lost landmarks of frames from the store's templates"},
    {"pairs", mim_cmd_pairs, "two-person pose-pairs (seed 002): coverage of true pose-pairs by samples"},
    {"demo", mim_cmd_demo, "everything end to end on synthetic data: store, index, vest, serve"},
};

static void usage(FILE *out)
{
    fprintf(out, "usage: mimic COMMAND [OPTIONS]\n\n"
                 "mimic keeps a store of human body meshes in many poses and transfers poses\n"
                 "to avatars. Commands:\n\n");
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(out, "  %-8s %s\n", commands[i].name, commands[i].what);
    fprintf(out, "\n`mimic COMMAND --help` describes a command. `mimic --version` prints the version.\n");
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("mimic %s\n", MIM_VERSION);
        return 0;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (!strcmp(argv[1], commands[i].name)) return commands[i].fn(argc - 1, argv + 1);
    fprintf(stderr, "mimic: unknown command '%s' (try mimic --help)\n", argv[1]);
    return 2;
}
