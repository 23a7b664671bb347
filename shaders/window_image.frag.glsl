// The engine's display image drawn into the window's image area (the viewport is the image's
// rectangle, possibly zoomed beyond the window). Image rows are stored top first; the window's y
// axis points up, so v is flipped.
uniform sampler2D image;
in vec2 uv;
layout(location = 0) out vec4 color;
void main() {
    color = vec4(texture(image, vec2(uv.x, 1.0 - uv.y)).rgb, 1.0);
}
