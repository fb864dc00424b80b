/* What any Vulkan program pays before its first command, without octovk: loading the driver
 * (dlopen of the ICD alone, RTLD_LAZY as the loader does), then vkCreateInstance,
 * vkEnumeratePhysicalDevices and vkCreateDevice with one queue, each timed, on stdout as one line.
 * Built and run by bench/startup.py; not part of the library or the tests.
 * Usage: vulkan_floor [ICD_LIBRARY]  (default: Debian's lavapipe) */
#include <dlfcn.h>
#include <stdio.h>
#include <time.h>
#include <vulkan/vulkan.h>

static double nowMs(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1e3 + t.tv_nsec / 1e6;
}

int main(int argc, char** argv) {
  const char* icd = argc > 1 ? argv[1] : "/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so";
  double t0 = nowMs();
  void* driver = dlopen(icd, RTLD_LAZY | RTLD_LOCAL);
  double t_dl = nowMs();
  if (!driver) {
    fprintf(stderr, "vulkan_floor: cannot load %s: %s\n", icd, dlerror());
    return 1;
  }
  /* The loader loads it again (a second reference, no cost): the steps below are Vulkan's own. */
  VkApplicationInfo app = {VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.apiVersion = VK_API_VERSION_1_2;
  VkInstanceCreateInfo ci = {VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &app;
  VkInstance instance;
  if (vkCreateInstance(&ci, NULL, &instance) != VK_SUCCESS) {
    fprintf(stderr, "vulkan_floor: vkCreateInstance failed\n");
    return 1;
  }
  double t_inst = nowMs();
  uint32_t n = 1;
  VkPhysicalDevice physical;
  if (vkEnumeratePhysicalDevices(instance, &n, &physical) < 0 || n == 0) {
    fprintf(stderr, "vulkan_floor: no physical device\n");
    return 1;
  }
  double t_phys = nowMs();
  float priority = 1.0f;
  VkDeviceQueueCreateInfo queue = {VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  queue.queueCount = 1;
  queue.pQueuePriorities = &priority;
  VkDeviceCreateInfo di = {VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  di.queueCreateInfoCount = 1;
  di.pQueueCreateInfos = &queue;
  VkDevice device;
  if (vkCreateDevice(physical, &di, NULL, &device) != VK_SUCCESS) {
    fprintf(stderr, "vulkan_floor: vkCreateDevice failed\n");
    return 1;
  }
  double t_dev = nowMs();
  vkDestroyDevice(device, NULL);
  vkDestroyInstance(instance, NULL);
  dlclose(driver);
  printf("dlopen %.1f instance %.1f physical %.1f device %.1f ms\n", t_dl - t0, t_inst - t_dl,
         t_phys - t_inst, t_dev - t_phys);
  return 0;
}
