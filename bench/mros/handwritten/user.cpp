/* The application code that consumes the data (benchmark baseline): the same job as ../user_generated.cpp. */
#include "ar_track_alvar_msgs/AlvarMarkers.h"
#include "robot_local_control_msgs/Status.h"

bool get_status(robot_local_control_msgs::Status &out);
bool get_markers(ar_track_alvar_msgs::AlvarMarkers &out);

static robot_local_control_msgs::Status status;
static ar_track_alvar_msgs::AlvarMarkers markers;

int user_poll(void)
{
    int n = 0;
    if (get_status(status)) {
        n += (int)status.robot_status.battery.level;
    }
    if (get_markers(markers)) {
        n += (int)markers.markers.size();
    }
    return n;
}
