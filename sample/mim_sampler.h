/* placeholder: the MCMC sampler of seed 002 (being written) */
#ifndef MIM_SAMPLER_H
#define MIM_SAMPLER_H
#include "mim_sample.h"
#endif
