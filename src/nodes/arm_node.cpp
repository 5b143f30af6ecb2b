#include "node_main.h"

int main(int argc, char** argv) { return massage_cell::nodes::runNodelet(argc, argv, "arm", "massage_cell/arm"); }
