/* Hand-written mROS application equivalent to the generated RB-1 adaptor (benchmark baseline). */
#include "app.h"
#include "ros.h"
#include "kernel_cfg.h"
#include "ar_track_alvar_msgs/AlvarMarkers.h"
#include "robot_local_control_msgs/Status.h"
#include "std_msgs/Float64.h"

#ifndef ROBOT_NS
#define ROBOT_NS "rb1_base"
#endif

/* the application's part, with do-nothing defaults */
bool fill_door(std_msgs::Float64 &msg);
void on_status(const robot_local_control_msgs::Status &msg);
void on_markers(const ar_track_alvar_msgs::AlvarMarkers &msg);

__attribute__((weak)) bool fill_door(std_msgs::Float64 &msg)
{
    (void)msg;
    return false;
}

__attribute__((weak)) void on_status(const robot_local_control_msgs::Status &msg)
{
    (void)msg;
}

__attribute__((weak)) void on_markers(const ar_track_alvar_msgs::AlvarMarkers &msg)
{
    (void)msg;
}

static robot_local_control_msgs::Status status_latest;
static bool status_received;
static ar_track_alvar_msgs::AlvarMarkers markers_latest;
static bool markers_received;
static std_msgs::Float64 door_msg;

bool get_status(robot_local_control_msgs::Status &out)
{
    bool ok;
    wai_sem(HW_LOCK_SEM);
    ok = status_received;
    if (ok) {
        out = status_latest;
    }
    sig_sem(HW_LOCK_SEM);
    return ok;
}

bool get_markers(ar_track_alvar_msgs::AlvarMarkers &out)
{
    bool ok;
    wai_sem(HW_LOCK_SEM);
    ok = markers_received;
    if (ok) {
        out = markers_latest;
    }
    sig_sem(HW_LOCK_SEM);
    return ok;
}

static void status_cb(robot_local_control_msgs::Status *msg)
{
    on_status(*msg);
    wai_sem(HW_LOCK_SEM);
    status_latest = *msg;
    status_received = true;
    sig_sem(HW_LOCK_SEM);
}

static void markers_cb(ar_track_alvar_msgs::AlvarMarkers *msg)
{
    on_markers(*msg);
    wai_sem(HW_LOCK_SEM);
    markers_latest = *msg;
    markers_received = true;
    sig_sem(HW_LOCK_SEM);
}

void hw_pub_task(intptr_t exinf)
{
    int argc = 0;
    char *argv = NULL;
    (void)exinf;
    ros::init(argc, argv, "rb1_pub");
    ros::NodeHandle n;
    ros::Publisher door = n.advertise<std_msgs::Float64>("/door1/door_controller/command", 10);
    ros::Rate rate(10);
    for (;;) {
        if (fill_door(door_msg)) {
            door.publish(door_msg);
        }
        rate.sleep();
    }
}

void hw_sub_task(intptr_t exinf)
{
    int argc = 0;
    char *argv = NULL;
    (void)exinf;
    ros::init(argc, argv, "rb1_sub");
    ros::NodeHandle n;
    n.subscribe("/" ROBOT_NS "/robot_local_control/state", 10, status_cb);
    n.subscribe("/" ROBOT_NS "/ar_pose_marker", 10, markers_cb);
    ros::spin();
}
