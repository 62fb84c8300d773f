/* TEST HARNESS (td2adaptor): control interface of the loopback bus in mros_stub_lib.cpp. */
#ifndef TD2A_MROS_STUB_BUS_H
#define TD2A_MROS_STUB_BUS_H

#include <string>
#include <vector>

namespace stub {

struct Endpoint {
    std::string node;
    std::string topic;
    std::string datatype;
    std::string md5;
    std::string definition;
    int type_id;
    int queue_size;
    bool publisher;
    void (*fp)(void *);
};

struct Sample {
    std::string topic;
    std::string bytes;  // mROS block: 4-byte length prefix, then the ROS 1 serialisation
};

/* Every advertise/subscribe so far, in order. */
std::vector<Endpoint> endpoints();
/* Every publish so far, in order. */
std::vector<Sample> published();
/* Deliver one ROS 1 serialisation (without prefix) to the subscribers of topic; how many were called. */
int inject(const std::string &topic, const std::string &body);
/* After n calls of ros::Rate::sleep a task thread exits (pthread_exit); 0: never. */
void set_sleep_limit(int n);
/* Every syslog line so far ("<level> <text>"). */
std::vector<std::string> log_lines();
/* Problems the stubs detected (memCopy writing other than dataSize() bytes, publish before advertise, ...). */
std::vector<std::string> problems();

}  // namespace stub

#endif /* TD2A_MROS_STUB_BUS_H */
