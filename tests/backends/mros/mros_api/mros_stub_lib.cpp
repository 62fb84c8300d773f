/* TEST HARNESS (td2adaptor): plays mROS's library translation unit (ros.cpp). Like ros.cpp it includes the
 * application's message_headers.h first and its message_class_specialization.h last, so a missing or
 * duplicated explicit instantiation fails here as it would there, and the template bodies use the traits,
 * dataSize/memCopy and the callback dispatch the way the library does. Transport is delegated to
 * mros_stub_services.h. Written for td2adaptor; no mROS code. */
#include <string>

#include "ros.h"
#include "message_headers.h"
#include "mros_stub_services.h"

void ros::init(int argc, char *argv, std::string node_name)
{
    (void)argc;
    (void)argv;
    stub_node(node_name.c_str());
}

template <class T> ros::Subscriber ros::NodeHandle::subscribe(std::string topic, int queue_size, void (*fp)(T))
{
    const int id = message_traits::DataTypeId<T>::value();
    Subscriber sub;
    sub.set(stub_add_endpoint(topic.c_str(), message_traits::DataType<T>::value(), id, getMD5Sum(id),
                              message_traits::Definition<T>::value(), queue_size, 0,
                              reinterpret_cast<void (*)(void *)>(reinterpret_cast<void (*)(void)>(fp))));
    return sub;
}

template <class T> ros::Publisher ros::NodeHandle::advertise(std::string topic, int queue_size)
{
    const int id = message_traits::DataTypeId<T *>::value();
    Publisher pub;
    pub.set(stub_add_endpoint(topic.c_str(), message_traits::DataType<T *>::value(), id, getMD5Sum(id),
                              message_traits::Definition<T *>::value(), queue_size, 1, 0));
    return pub;
}

template <class T> void ros::Publisher::publish(T &data)
{
    const unsigned int size = (unsigned int)data.dataSize();
    char *block = stub_alloc(this->get(), size + 4u);
    if (block == 0) {
        ROS_ERROR("publish: no block for %u bytes", size);
        return;
    }
    /* as ros.cpp: the body goes after mROS's 4-byte length word, which the library itself leaves unwritten
     * for subscribers on the same board (stub_alloc fills the block with a pattern) */
    char *body = block + 4;
    data.memCopy(body);
    stub_sent(this->get(), block, size + 4u, body);
}

void ros::Rate::sleep(void)
{
    stub_sleep(rate_);
}

void ros::spin(void)
{
    (void)slp_tsk();
}

void mros_topic_callback(int type_id, void (*fp)(void *), char *block)
{
    callCallback(type_id, fp, block);
}

#include "message_class_specialization.h"
