/* TEST HARNESS (td2adaptor): host loopback bus behind mros_stub_lib.cpp, plus the TOPPERS services
 * (semaphores as one mutex, syslog into a log) the generated code calls. Written for td2adaptor. */
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include <string>
#include <vector>

#include "kernel.h"
#include "mros_stub_bus.h"
#include "mros_stub_services.h"

namespace {

pthread_mutex_t bus_lock = PTHREAD_MUTEX_INITIALIZER;
pthread_mutex_t sem_lock = PTHREAD_MUTEX_INITIALIZER;
std::vector<stub::Endpoint> g_endpoints;
std::vector<stub::Sample> g_published;
std::vector<std::string> g_log;
std::vector<std::string> g_problems;
std::vector<std::vector<char> > g_blocks;
int g_sleep_limit = 0;
__thread int t_sleeps = 0;
__thread char t_node[64];

struct Guard {
    Guard() { pthread_mutex_lock(&bus_lock); }
    ~Guard() { pthread_mutex_unlock(&bus_lock); }
};

const size_t GUARD_BYTES = 16;

int deliver(const std::string &topic, const std::string &block)
{
    std::vector<stub::Endpoint> subs;
    {
        Guard g;
        for (size_t i = 0; i < g_endpoints.size(); ++i) {
            if (!g_endpoints[i].publisher && g_endpoints[i].topic == topic) {
                subs.push_back(g_endpoints[i]);
            }
        }
    }
    for (size_t i = 0; i < subs.size(); ++i) {
        std::vector<char> buf(block.begin(), block.end());
        buf.push_back('\0');
        mros_topic_callback(subs[i].type_id, subs[i].fp, &buf[0]);
    }
    return (int)subs.size();
}

size_t endpoint_index(void *publisher)
{
    return reinterpret_cast<size_t>(publisher);
}

}  // namespace

extern "C" {

void stub_node(const char *name)
{
    if (name[0] == '\0' || strlen(name) >= sizeof(t_node)) {
        Guard g;
        g_problems.push_back(std::string("bad node name '") + name + "'");
    }
    strncpy(t_node, name, sizeof(t_node) - 1);
}

void *stub_add_endpoint(const char *topic, const char *datatype, int type_id, const char *md5,
                        const char *definition, int queue_size, int publisher, void (*fp)(void *))
{
    Guard g;
    stub::Endpoint e;
    e.node = t_node;
    e.topic = topic;
    e.datatype = datatype;
    e.type_id = type_id;
    e.md5 = md5 ? md5 : "";
    e.definition = definition;
    e.queue_size = queue_size;
    e.publisher = publisher != 0;
    e.fp = fp;
    if (t_node[0] == '\0') {
        g_problems.push_back("advertise/subscribe of " + e.topic + " before ros::init in this task");
    }
    if (e.md5.size() != 32) {
        g_problems.push_back("getMD5Sum gave no md5 for " + e.topic);
    }
    g_endpoints.push_back(e);
    return reinterpret_cast<void *>(g_endpoints.size());
}

char *stub_alloc(void *publisher, unsigned int size)
{
    Guard g;
    size_t index = endpoint_index(publisher);
    if (index == 0 || index > g_endpoints.size() || !g_endpoints[index - 1].publisher) {
        g_problems.push_back("publish on a publisher that was not advertised");
        return 0;
    }
    g_blocks.push_back(std::vector<char>(size + GUARD_BYTES, '\x5a'));
    /* a reused pool block: mROS's publish leaves its length word as it was (here: 0, which no message with
     * a field decodes from), so only a memCopy that writes it itself reaches same-board subscribers */
    memset(&g_blocks.back()[0], 0, 4);
    return &g_blocks.back()[0];
}

void stub_sent(void *publisher, char *block, unsigned int size, const char *written_end)
{
    std::string topic;
    {
        Guard g;
        topic = g_endpoints[endpoint_index(publisher) - 1].topic;
        if (written_end != block + size) {
            g_problems.push_back("memCopy of " + topic + " wrote a different number of bytes than dataSize()");
        }
        for (size_t i = 0; i < GUARD_BYTES; ++i) {
            if (block[size + i] != '\x5a') {
                g_problems.push_back("memCopy of " + topic + " wrote beyond its block");
                break;
            }
        }
        stub::Sample s;
        s.topic = topic;
        s.bytes.assign(block, size);
        g_published.push_back(s);
    }
    deliver(topic, std::string(block, size));
}

void stub_sleep(int rate)
{
    usleep(rate > 0 ? 1000 : 0);
    if (g_sleep_limit > 0 && ++t_sleeps >= g_sleep_limit) {
        t_sleeps = 0;
        pthread_exit(NULL);
    }
}

ER act_tsk(ID tskid)
{
    (void)tskid;
    return E_OK;
}

ER slp_tsk(void)
{
    return E_OK;
}

ER dly_tsk(RELTIM dlytim)
{
    usleep(dlytim * 1000u);
    return E_OK;
}

ER wai_sem(ID semid)
{
    (void)semid;
    pthread_mutex_lock(&sem_lock);
    return E_OK;
}

ER sig_sem(ID semid)
{
    (void)semid;
    pthread_mutex_unlock(&sem_lock);
    return E_OK;
}

void syslog(unsigned int prio, const char *format, ...)
{
    char text[512];
    char line[540];
    va_list ap;
    va_start(ap, format);
    vsnprintf(text, sizeof(text), format, ap);
    va_end(ap);
    snprintf(line, sizeof(line), "%u %s", prio, text);
    Guard g;
    g_log.push_back(line);
}

}  // extern "C"

std::vector<stub::Endpoint> stub::endpoints()
{
    Guard g;
    return g_endpoints;
}

std::vector<stub::Sample> stub::published()
{
    Guard g;
    return g_published;
}

int stub::inject(const std::string &topic, const std::string &body)
{
    uint32_t n = (uint32_t)body.size();
    std::string block(4, '\0');
    memcpy(&block[0], &n, 4);
    return deliver(topic, block + body);
}

void stub::set_sleep_limit(int n)
{
    g_sleep_limit = n;
}

std::vector<std::string> stub::log_lines()
{
    Guard g;
    return g_log;
}

std::vector<std::string> stub::problems()
{
    Guard g;
    return g_problems;
}
