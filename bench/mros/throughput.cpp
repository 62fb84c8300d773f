/* Host encode/decode throughput of generated mROS message classes (bench/backend_mros.py).
 * stdin: lines "<name> <iterations> <hex of a ROS 1 serialisation>" for the RB-1 types below; stdout per line:
 * "<name> <bytes> <decodes per second> <encodes per second> <ok>", where ok says the re-encoding equals the
 * input. Written for td2adaptor's benchmark. */
#include <chrono>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "ar_track_alvar_msgs/AlvarMarkers.h"
#include "robot_local_control_msgs/Status.h"
#include "std_msgs/Float64.h"

static std::string unhex(const std::string &h)
{
    std::string out;
    for (size_t i = 0; i + 1 < h.size(); i += 2) out += (char)std::stoi(h.substr(i, 2), nullptr, 16);
    return out;
}

template <class M> static void run(const std::string &name, long n, const std::string &bytes)
{
    using clock = std::chrono::steady_clock;
    std::vector<char> in(bytes.begin(), bytes.end());
    in.push_back(0);
    volatile bool ok = true;
    auto t0 = clock::now();
    for (long i = 0; i < n; ++i) {
        M fresh;  // as CallCallbackFuncs does for every received message: a new object, then decode
        char *p = &in[0];
        uint32_t rem = (uint32_t)bytes.size();
        ok = fresh.td2a_read(p, rem) && ok;
        asm volatile("" : : "r"(p) : "memory");  // keep every iteration
    }
    M m;
    {
        char *p = &in[0];
        uint32_t rem = (uint32_t)bytes.size();
        ok = m.td2a_read(p, rem) && ok;
    }
    auto t1 = clock::now();
    std::vector<char> out((size_t)m.dataSize() + 1);
    for (long i = 0; i < n; ++i) {
        char *p = &out[0];
        out.resize((size_t)m.dataSize() + 1);  // what publish does: dataSize(), then the serialisation
        m.td2a_write(p);
        asm volatile("" : : "r"(p) : "memory");
    }
    auto t2 = clock::now();
    double dec = std::chrono::duration<double>(t1 - t0).count(), enc = std::chrono::duration<double>(t2 - t1).count();
    bool same = ok && std::string(out.begin(), out.begin() + m.dataSize()) == bytes;
    std::printf("%s %zu %.0f %.0f %d\n", name.c_str(), bytes.size(), n / dec, n / enc, same ? 1 : 0);
    std::fflush(stdout);
}

int main()
{
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string name, hex;
        long n;
        in >> name >> n >> hex;
        std::string bytes = unhex(hex);
        if (name.rfind("Status", 0) == 0) run<robot_local_control_msgs::Status>(name, n, bytes);
        else if (name.rfind("AlvarMarkers", 0) == 0) run<ar_track_alvar_msgs::AlvarMarkers>(name, n, bytes);
        else if (name.rfind("Float64", 0) == 0) run<std_msgs::Float64>(name, n, bytes);
        else std::printf("%s unknown\n", name.c_str());
    }
}
