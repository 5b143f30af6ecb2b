#include "node_main.h"

int main(int argc, char** argv) {
  return massage_cell::nodes::runNodelet(argc, argv, "camera", "massage_cell/mono_camera");
}
