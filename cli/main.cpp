#include <cstdio>
int main() { std::puts("facetree"); return 0; }
