#version 450 core
// coverage.frag: depth only (coverage.vert says why).
void main() {
}
