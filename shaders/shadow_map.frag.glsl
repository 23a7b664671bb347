// Writes the normalised depth (0 nearest the light) of the closest surface; cleared to 1.
in float depth;
layout(location = 0) out float shadow_depth;
void main() {
    shadow_depth = depth;
}
