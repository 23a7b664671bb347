// The ground plane under the person (viewer/scene/ground.py): normal . p = offset in camera space, seen
// through the pixels of a pass at some fraction of the work resolution (its own focal length and
// centre, rows from the top).
uniform vec3 ground_normal;    // unit, pointing up
uniform float ground_offset;   // metres (a plane below the camera: < 0)
uniform vec2 focal_center_px;
uniform float focal_px;

// The plane's point seen through pixel position q; false at or above the plane's horizon.
bool ground_point(vec2 q, out vec3 p) {
    vec3 view = vec3((q.x - focal_center_px.x) / focal_px, -(q.y - focal_center_px.y) / focal_px, -1.0);
    float facing = dot(ground_normal, view);
    p = vec3(0.0);
    if (facing >= -1e-6) return false;
    p = view * (ground_offset / facing);
    return true;
}
