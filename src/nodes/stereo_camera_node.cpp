#include "node_main.h"

int main(int argc, char** argv) {
  return massage_cell::nodes::runNodelet(argc, argv, "stereo_camera", "massage_cell/stereo_camera");
}
