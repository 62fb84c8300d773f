/* Hand-written glue (benchmark baseline): the instantiations the application needs. */
#ifndef HW_MESSAGE_CLASS_SPECIALIZATION_H
#define HW_MESSAGE_CLASS_SPECIALIZATION_H

template ros::Subscriber ros::NodeHandle::subscribe(std::string, int, void (*fp)(robot_local_control_msgs::Status *));
template ros::Subscriber ros::NodeHandle::subscribe(std::string, int, void (*fp)(ar_track_alvar_msgs::AlvarMarkers *));
template ros::Publisher ros::NodeHandle::advertise<std_msgs::Float64>(std::string, int);
template void ros::Publisher::publish(std_msgs::Float64 &);

#endif
