// broken.glsl: a library function with one deliberate error, marked below.
//   float broken_value(float x)

float broken_value(float x)
{
    float y = 3.0 * x;
    return y + undeclaredThing;  // BROKEN: undeclared identifier
}
