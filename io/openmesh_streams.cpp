// OpenMesh reports on its own global streams (omerr, omlog, omout), which
// are not thread-safe, and whose multiplexing buffer deadlocks on a long
// message (it re-locks its own mutex when it overflows), which a malformed
// file can trigger. mimic reports every problem itself, so both shims
// (read_openmesh.cpp, write_openmesh.cpp) give those streams, once, a
// buffer that discards everything.
#include "openmesh_streams.h"

#include <OpenMesh/Core/System/omstream.hh>

#include <mutex>
#include <streambuf>

namespace {

// A stream buffer that accepts and drops every character.
class NullBuffer : public std::streambuf {
protected:
    int overflow(int c) override { return traits_type::not_eof(c); }
    std::streamsize xsputn(const char *, std::streamsize n) override { return n; }
};

std::once_flag quiet_once;

} // namespace

void mim__openmesh_quiet()
{
    std::call_once(quiet_once, [] {
        static NullBuffer sink;
        omerr().rdbuf(&sink);
        omlog().rdbuf(&sink);
        omout().rdbuf(&sink);
    });
}
