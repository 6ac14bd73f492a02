#ifndef GR_VERSION_H
#define GR_VERSION_H
#define GRADUS_VERSION "0.1.0"
#endif
