/* mimic vest: the PrioVR / YOST 3-Space streaming protocol, transports
 * (serial, HID, replay, UDP), calibration and forward kinematics from sensor
 * orientations to the avatar's landmarks, and a simulated vest.
 *
 * Computation and I/O only: this module never opens the template store.
 * This umbrella includes every public vest header; new code should include
 * only the narrow ones it needs:
 *   mim_vest_protocol.h    wire constants, command and stream packet encoders
 *   mim_vest_decode.h      stream decoder, assembly into whole vest frames
 *   mim_vest_kinematics.h  segments, skeleton, calibration, forward kinematics
 *   mim_vest_transport.h   serial/HID/UDP/replay links, recordings, UDP
 *                          landmark frames, device list
 *   mim_vest_motion.h      BVH and ASF/AMC motion, the built-in demo motion
 *   mim_vest_simulate.h    the simulated vest */
#ifndef MIM_VEST_H
#define MIM_VEST_H

#include "mim_vest_protocol.h"
#include "mim_vest_decode.h"
#include "mim_vest_kinematics.h"
#include "mim_vest_transport.h"
#include "mim_vest_motion.h"
#include "mim_vest_simulate.h"

#endif
