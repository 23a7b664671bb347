// Shadow map: orthographic view of the depth mesh from one light (viewer.scene.shadow_space frame).
in vec3 position;
uniform mat4 light_frame;
out float depth;
void main() {
    vec3 uvz = (light_frame * vec4(position, 1.0)).xyz;
    depth = uvz.z;
    gl_Position = vec4(uvz * 2.0 - 1.0, 1.0);
}
