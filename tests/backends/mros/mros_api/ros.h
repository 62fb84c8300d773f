/* TEST HARNESS (td2adaptor): our stand-in for mROS v1.3 ros.h (mROS-base/mROS 741b884), public API only. */
#ifndef _ROS_H_
#define _ROS_H_

#include <string>

namespace ros {

void init(int argc, char *argv, std::string node_name);

class Publisher {
public:
    template <class T> void publish(T &data);
    void set(void *cobj) { cobj_ = cobj; }
    void *get() { return cobj_; }

private:
    void *cobj_;
};

class Subscriber {
public:
    void set(void *cobj) { cobj_ = cobj; }
    void *get() { return cobj_; }

private:
    void *cobj_;
};

class NodeHandle {
public:
    template <class T> Subscriber subscribe(std::string topic, int queue_size, void (*fp)(T));
    template <class T> Publisher advertise(std::string topic, int queue_size);
};

class Rate {
public:
    Rate(int rate) : rate_(rate) {}
    void sleep(void);

private:
    int rate_;
};

void spin(void);

}  // namespace ros

namespace message_traits {
template <int V> struct MD5Sum {
    static const char *value();
};
template <class T> struct DataType {
    static const char *value();
};
template <class T> struct DataTypeId {
    static int value(void);
};
template <class T> struct Definition {
    static const char *value();
};
}  // namespace message_traits

namespace subtask_methods {
template <int T> struct CallCallbackFuncs {
    static void call(void (*fp)(void *), char *rbuf);
};
}  // namespace subtask_methods

#include "mros_log.h"

#endif /* _ROS_H_ */
