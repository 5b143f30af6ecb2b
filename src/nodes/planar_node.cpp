#include "node_main.h"

int main(int argc, char** argv) { return massage_cell::nodes::runNodelet(argc, argv, "planar", "massage_cell/planar"); }
