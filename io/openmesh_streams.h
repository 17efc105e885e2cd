// Internal to io/ (C++ only): silences OpenMesh's global log streams, once
// per process, before a shim calls OpenMesh (openmesh_streams.cpp says why).
#ifndef MIM_IO_OPENMESH_STREAMS_H
#define MIM_IO_OPENMESH_STREAMS_H

void mim__openmesh_quiet();

#endif
