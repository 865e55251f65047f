// EXPECT_FACETREE_ERROR / ASSERT_FACETREE_ERROR(statement, Category): the statement throws a
// facetree::Error of ErrorCategory::Category.
#pragma once

#include <gtest/gtest.h>

#include "facetree/error.h"

#define FACETREE_ERROR_CHECK_(kind, statement, expected)                             \
  kind##_THROW(                                                                      \
      {                                                                              \
        try {                                                                        \
          statement;                                                                 \
        } catch (const ::facetree::Error& facetree_error_) {                         \
          EXPECT_EQ(facetree_error_.category(), ::facetree::ErrorCategory::expected) \
              << facetree_error_.what();                                             \
          throw;                                                                     \
        }                                                                            \
      },                                                                             \
      ::facetree::Error)
#define EXPECT_FACETREE_ERROR(statement, expected) FACETREE_ERROR_CHECK_(EXPECT, statement, expected)
#define ASSERT_FACETREE_ERROR(statement, expected) FACETREE_ERROR_CHECK_(ASSERT, statement, expected)
