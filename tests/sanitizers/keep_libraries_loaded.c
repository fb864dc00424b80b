/* Preloaded by scripts/sanitize.sh into every process of the sanitizer run: dlclose() does
 * nothing, so no shared library is unmapped before LeakSanitizer looks for leaks at exit.
 *
 * Why: the Vulkan loader (Debian bookworm's 1.3.239) dlcloses the drivers it opened when the
 * process exits, before LeakSanitizer's check runs. Memory a driver still holds in its globals
 * (lavapipe keeps a 128-byte realloc'd block) then looks leaked, and its stack frames show as
 * "<unknown module>", so no suppression could even name the driver. With the libraries kept,
 * driver globals are scanned as roots and driver frames are symbolized. Newer loaders do the
 * same with VK_LOADER_DISABLE_DYNAMIC_LIBRARY_UNLOADING=1, which the script sets as well.
 *
 * Built with -nostdlib: it depends on nothing and defines nothing else, so the sanitizer
 * runtime still provides malloc and the rest (the script sets verify_asan_link_order=0 because
 * this library, not the runtime, comes first in the link order). */
int dlclose(void *handle) {
  (void)handle;
  return 0;
}
