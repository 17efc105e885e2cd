/* The subcommands of the `mimic` binary. Each takes argv with argv[0] = the
 * subcommand name, prints its own --help, and returns the process exit status:
 * 0 success, 1 some input failed (reported), 2 bad usage. */
#ifndef MIM_CLI_COMMANDS_H
#define MIM_CLI_COMMANDS_H

int mim_cmd_synth(int argc, char **argv);
int mim_cmd_ingest(int argc, char **argv);
int mim_cmd_info(int argc, char **argv);
int mim_cmd_store(int argc, char **argv);
int mim_cmd_list(int argc, char **argv);
int mim_cmd_index(int argc, char **argv);
int mim_cmd_query(int argc, char **argv);
int mim_cmd_vest(int argc, char **argv);
int mim_cmd_transfer(int argc, char **argv);
int mim_cmd_morph(int argc, char **argv);
int mim_cmd_serve(int argc, char **argv);
int mim_cmd_demo(int argc, char **argv);
int mim_cmd_register(int argc, char **argv);
int mim_cmd_landmarks(int argc, char **argv);
int mim_cmd_pairs(int argc, char **argv);
int mim_cmd_complete(int argc, char **argv);
int mim_cmd_pairs_sample(int argc, char **argv);    /* mimic pairs sample */
int mim_cmd_pairs_templates(int argc, char **argv); /* mimic pairs templates */
int mim_cmd_pairs_retrieve(int argc, char **argv);  /* mimic pairs retrieve */
int mim_cmd_pairs_complete(int argc, char **argv);  /* mimic pairs complete */

#endif
